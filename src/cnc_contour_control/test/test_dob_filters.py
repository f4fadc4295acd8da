"""The per-sample filters of the disturbance laws against scipy.signal.lfilter."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import signal

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.velocity_models import PAPER002_MODELS
from cnc_contour_control.disturbance.design import dob_filters, mbda_pi, q_filter
from cnc_contour_control.disturbance.filters import FirFilter, IirFilter

RNG = np.random.default_rng(2)
SIGNAL = RNG.normal(size=400)


def _cases() -> list[tuple[tuple[float, ...], tuple[float, ...]]]:
    model = PAPER002_MODELS["x"]
    q = q_filter(3, 1, 0.005, model)
    inverse, shifted = dob_filters(q, model)
    return [(model.numerator, model.denominator), q, inverse, shifted, mbda_pi(1.0, 100.0, 0.001),
            ((0.5,), (2.0,)), ((1.0, 2.0, 3.0, 4.0), (1.0, -0.5))]


@pytest.mark.parametrize("numerator, denominator", _cases())
def test_iir_matches_lfilter(numerator: tuple[float, ...], denominator: tuple[float, ...]) -> None:
    flt = IirFilter(numerator, denominator)
    ours = [flt.step(x) for x in SIGNAL]
    assert_allclose(ours, signal.lfilter(numerator, denominator, SIGNAL), rtol=1e-9, atol=1e-9)
    flt.reset()
    assert_allclose(flt.step(1.0), numerator[0] / denominator[0])


@pytest.mark.parametrize("taps", [(1.0,), (0.2, -0.5, 0.3), tuple(RNG.normal(size=15))])
def test_fir_matches_lfilter(taps: tuple[float, ...]) -> None:
    flt = FirFilter(taps)
    assert_allclose([flt.step(x) for x in SIGNAL], signal.lfilter(taps, [1.0], SIGNAL), rtol=1e-12, atol=1e-12)


def test_fir_new_taps_keep_the_input_history() -> None:
    old, new = (1.0, 0.5, 0.25), (0.1, 0.2, 0.3, 0.4)
    flt = FirFilter(old)
    for x in SIGNAL[:50]:
        flt.step(x)
    flt.set_taps(new)
    # the next output is the new filter over the signal's past (x(k−3) was still in the delay line)
    assert flt.step(SIGNAL[50]) == pytest.approx(signal.lfilter(new, [1.0], SIGNAL[:51])[-1])
    flt.set_taps(old[:2])
    assert flt.step(SIGNAL[51]) == pytest.approx(signal.lfilter(old[:2], [1.0], SIGNAL[:52])[-1])


def test_bad_coefficients_are_refused() -> None:
    with pytest.raises(ConfigError, match="denominator\\[0\\] must be nonzero"):
        IirFilter((1.0,), (0.0, 1.0))
    with pytest.raises(ConfigError, match="taps must have at least one"):
        FirFilter(())
