"""The turning process of paper 004: the exact lag against scipy.signal, the force law, the schedule, bad input."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import signal

from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.force_model import FirstOrderLag
from cnc_contour_control.core.units import MM_MIN_PER_M_S
from cnc_plant_sim.process.turning import TurningConfig, TurningProcess


def _velocity_m_s(feed_mm_rev: float, rpm: float = 600.0) -> float:
    return feed_mm_rev * rpm / MM_MIN_PER_M_S


@pytest.mark.parametrize("tau_s, dt_s", [(0.17, 1e-3), (0.0632, 0.01), (0.5, 0.05)])
def test_first_order_lag_equals_scipy_zoh(tau_s: float, dt_s: float) -> None:
    u = np.random.default_rng(3).normal(size=200)
    continuous = tuple(np.array(m) for m in ([[-1.0 / tau_s]], [[1.0 / tau_s]], [[1.0]], [[0.0]]))
    a, b, c, d, _ = signal.cont2discrete(continuous, dt_s, method="zoh")
    _, expected, _ = signal.dlsim((a, b, c, d, dt_s), u)
    lag = FirstOrderLag(tau_s)
    ours = [lag.step(dt_s, x) for x in u]
    # dlsim's output y[k] is the state before input k: ours after it, so shift by one sample
    assert_allclose(ours[:-1], expected[1:, 0], atol=1e-12)


def test_chip_time_constant_is_eq4() -> None:
    assert TurningConfig(spindle_rpm=600.0).chip_tau_s == pytest.approx(60.0 * (1.0 - math.exp(-1.0)) / 600.0)
    assert TurningConfig(spindle_rpm=1200.0).chip_tau_s == pytest.approx(0.0316, abs=1e-4)


def test_force_step_response_is_the_first_order_lag() -> None:
    process = TurningProcess(TurningConfig(depth_schedule=((0.0, 2.0),)))
    dt_s, tau = 1e-3, process.config.chip_tau_s
    forces = np.array([process.step(_velocity_m_s(0.15), dt_s) for _ in range(300)])
    t = dt_s * np.arange(1, 301)
    assert_allclose(forces, 1773.0 * 2.0 * 0.15 * (1.0 - np.exp(-t / tau)), rtol=1e-9)


def test_depth_follows_the_schedule_and_can_be_held_on_line() -> None:
    process = TurningProcess(TurningConfig(depth_schedule=((0.0, 1.0), (0.05, 3.0))))
    depths = []
    for _ in range(100):
        depths.append(process.depth_mm())
        process.step(_velocity_m_s(0.2), 1e-3)
    assert depths[10] == 1.0 and depths[60] == 3.0
    process.set_depth_mm(0.5)
    process.step(_velocity_m_s(0.2), 1e-3)
    assert process.depth_mm() == 0.5
    process.set_depth_mm(None)
    assert process.depth_mm() == 3.0
    with pytest.raises(ConfigError, match="depth_mm must be >= 0, got -1"):
        process.set_depth_mm(-1.0)


def test_steady_force_is_ks_d_f() -> None:
    process = TurningProcess(TurningConfig(depth_schedule=((0.0, 3.0),)))
    for _ in range(2000):
        force = process.step(-_velocity_m_s(0.1), 1e-3)   # the sign of the feed direction does not matter
    assert force == pytest.approx(1773.0 * 3.0 * 0.1, rel=1e-9)


@pytest.mark.parametrize("schedule, message", [
    (((0.0, 1.0), (4.0, -2.0)), r"depth_schedule\[1\].depth_mm must be >= 0, got -2"),
    (((4.0, 1.0), (0.0, 2.0)), r"depth_schedule\[1\].t_s must be > 4.0 \(sorted\), got 0.0"),
    (((0.0, 1.0), (0.0, 2.0)), r"depth_schedule\[1\].t_s must be > 0.0"),
    ((), "non-empty"),
    (((0.0, 1.0, 2.0),), r"depth_schedule\[0\] must be \[t_s, depth_mm\]"),
    (((0.0, float("nan")),), r"depth_schedule\[0\].depth_mm must be finite, got nan"),
])
def test_bad_schedules_are_refused(schedule: tuple, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        TurningConfig(depth_schedule=schedule)


def test_config_from_yaml_lists_and_bounds() -> None:
    config = build_config(TurningConfig, {"depth_schedule": [[0, 1], [4, 2]], "noise_n": 2})
    assert config.depth_schedule == ((0.0, 1.0), (4.0, 2.0)) and config.noise_n == 2.0
    with pytest.raises(ConfigError, match="spindle_rpm must be in"):
        TurningConfig(spindle_rpm=0.0)
    with pytest.raises(ConfigError, match="unknown key"):
        build_config(TurningConfig, {"depth": 1.0})


def test_noise_is_seeded_and_has_its_deviation() -> None:
    def run(seed: int) -> np.ndarray:
        process = TurningProcess(TurningConfig(noise_n=5.0, seed=seed))
        process.reset(300.0)
        return np.array([process.step(_velocity_m_s(300.0 / 1773.0), 1e-3) for _ in range(4000)])

    first, again, other = run(1), run(1), run(2)
    assert_allclose(first, again)
    assert not np.allclose(first, other)
    assert np.std(first - 300.0) == pytest.approx(5.0, rel=0.1)


def test_dynamometer_lag_delays_the_measurement() -> None:
    plain = TurningProcess(TurningConfig())
    lagged = TurningProcess(TurningConfig(dynamometer_tau_s=0.02))
    a = [plain.step(_velocity_m_s(0.2), 1e-3) for _ in range(50)]
    b = [lagged.step(_velocity_m_s(0.2), 1e-3) for _ in range(50)]
    assert all(y < x for x, y in zip(a, b))
    assert lagged.force_n == pytest.approx(a[-1])      # the true force is the same


def test_non_finite_feed_faults() -> None:
    with pytest.raises(FaultError, match="feed_velocity_m_s must be finite, got nan"):
        TurningProcess(TurningConfig()).step(float("nan"), 1e-3)
