"""The on-line f_d estimate of the tracking PDC: its shifted line against scipy, its accuracy, its gates, the grid."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import signal

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.disturbance.tracking import (
    RESOLUTION,
    FrequencyTracker,
    TrackerConfig,
    tracked_rpm,
)
from cnc_contour_control.laws import LawSample, law_config, make_law
from cnc_contour_control.laws.disturbance import DisturbanceLaw, PdcConfig

T_S = 1e-3
RNG = np.random.default_rng(7)


def _residual(f_hz: float, samples: int, noise: float = 2e-4) -> np.ndarray:
    """A 1.2e-3 line at ``f_hz`` with friction-like steps and white noise (the PDC residual's kind)."""
    t = np.arange(samples) * T_S
    return (1.2e-3 * np.sin(2 * np.pi * f_hz * t + 0.3) + 2e-5 * np.sign(np.sin(2 * np.pi * 0.3 * t))
            + RNG.normal(0.0, noise, samples))


def test_the_shifted_line_is_scipys_lowpass_of_the_demodulated_residual() -> None:
    config = TrackerConfig(50.0, T_S)
    tracker, rho = FrequencyTracker(config), _residual(48.0, 600)
    ours = [tracker.shifted(float(r)) for r in rho]
    b, a = signal.butter(2, 5.0, fs=1.0 / T_S)
    demodulated = rho * np.exp(-2j * np.pi * 50.0 * T_S * np.arange(rho.size))
    assert_allclose(ours, signal.lfilter(b, a, demodulated), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("f_hz", [46.5, 48.0, 50.0, 52.0, 53.5])
def test_the_estimate_finds_the_line_within_the_band(f_hz: float) -> None:
    tracker = FrequencyTracker(TrackerConfig(50.0, T_S, averaging_s=0.1))
    estimates = np.array([tracker.step(float(r)) or np.nan for r in _residual(f_hz, 2000)])
    assert np.all(np.isnan(estimates[:150]))  # settling
    assert np.max(np.abs(estimates[600:] - f_hz)) < 0.15  # 0.3 % of f_d: under the redesign grid's 0.5 %


def test_no_line_no_estimate_and_the_band_clamps() -> None:
    quiet = FrequencyTracker(TrackerConfig(50.0, T_S, min_amplitude=1e-4))
    assert all(quiet.step(float(r)) is None for r in _residual(50.0, 800, noise=1e-6) * 0.01)
    narrow = FrequencyTracker(TrackerConfig(50.0, T_S, band=0.02))
    last = [narrow.step(float(r)) for r in _residual(53.0, 1000)][-1]
    assert last == pytest.approx(51.0)


@pytest.mark.parametrize("kwargs, message", [
    ({"band": 0.6}, r"band must be in \[0.01, 0.5\], got 0.6"),
    ({"center_hz": 480.0}, r"center_hz · \(1 \+ band\) must be in \(0, 500\) Hz .* got 528"),
    ({"averaging_s": 1e-4}, "averaging_s must be in"),
])
def test_bad_tracker_settings_are_refused_by_name(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        TrackerConfig(**{"center_hz": 50.0, "sample_time_s": T_S, **kwargs})


def test_the_redesign_grid_and_its_hysteresis() -> None:
    assert tracked_rpm(1500.0, 50.0, 50.1, 1500.0) is None  # within 0.75 grid steps
    assert tracked_rpm(1500.0, 50.0, 46.6, 1500.0) == pytest.approx(1500.0 * (1 - 14 * RESOLUTION))
    assert tracked_rpm(1500.0, 50.0, 46.6, 1500.0 * (1 - 14 * RESOLUTION)) is None


def test_a_pdc_law_refuses_a_tracked_band_past_nyquist() -> None:
    with pytest.raises(ConfigError, match="pdc.track_band: center_hz"):
        law_config("pdc", {"spindle_rpm": 8000.0, "flutes": 3, "track_fd": True, "track_band": 0.3})


def test_the_law_redesigns_for_the_tracked_speed_and_back_on_a_retune() -> None:
    """Residual = what the law sees when y − P_n v is a 53 Hz line: H moves to the grid speed nearest 1590 rpm."""
    law = make_law("pdc", {"kp": 40.0, "track_fd": True})
    assert isinstance(law, DisturbanceLaw)
    sample = LawSample(dt_s=T_S)
    for r in _residual(53.0, 1500):
        sample.velocity_counts_s = float(r)  # v = 0: the residual is y
        law.step(sample)
    assert law.design_rpm == pytest.approx(1590.0, abs=1500.0 * RESOLUTION)
    assert law.design.f_d_hz == pytest.approx(53.0, abs=50.0 * RESOLUTION)
    assert law.tracked_redesigns >= 1
    assert law._tracker is not None and law._tracker.estimate_hz is not None
    law.reset()  # a restart: the estimate starts over, H keeps the tracked design until a new estimate
    assert law._tracker.estimate_hz is None and law.design_rpm != 1500.0
    config = law.config
    assert isinstance(config, PdcConfig) and config.spindle_rpm == 1500.0  # the commanded speed stays
    law.retune(config)
    assert law.design_rpm == 1500.0
