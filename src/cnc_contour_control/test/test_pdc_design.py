"""Design checks of paper 002's PDC, DOB and MBDA filters (docs/paper002_design.md has the numbers)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import signal
from scipy.special import comb

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.velocity_models import PAPER002_MODELS
from cnc_contour_control.disturbance.design import (
    design_pdc,
    linear_phase_lowpass,
    mbda_pi,
    q_filter,
    q_filter_continuous,
    response,
    rls_fit,
)
from cnc_contour_control.laws import law_config

T_S = 0.001
RADII = (0.9, 0.8, 0.85)
PRINTED_PI = (1.3, 1.57, 1.86)  # paper 002's zero angles as printed [π rad]
NEGATED_PI = (0.3, 0.57, 0.86)  # the same zeros negated: −z_k = r_k e^{j(θ_k − π)}
#: Paper 002's W for its models (Section IV).
PAPER_W = {"x": (9.915, -21.856, 11.276), "y": (13.102, -29.523, 15.766)}


def _angles(angles_pi: tuple[float, ...]) -> tuple[float, ...]:
    return tuple(math.pi * a for a in angles_pi)


def test_negated_zeros_give_the_papers_lowpass() -> None:
    taps = linear_phase_lowpass(RADII, _angles(NEGATED_PI), 12)
    assert_allclose(taps, taps[::-1])  # linear phase: symmetric about D_L = 6
    assert np.sum(taps) == pytest.approx(1.0)
    at_50 = complex(response(taps, [1.0], 50.0, T_S)[0])
    assert abs(at_50) == pytest.approx(0.7, abs=0.015)  # paper: M_L(50) = 0.7; ours 0.688
    assert math.degrees(np.angle(at_50)) == pytest.approx(-360.0 * 50.0 * T_S * 6)  # a delay of 6 samples
    assert np.max(np.abs(signal.freqz(taps, 1, worN=512)[1])) <= 1.0 + 1e-9


def test_printed_zeros_give_a_highpass_and_are_refused() -> None:
    with pytest.raises(ConfigError, match="no low-pass: max \\|L\\| must be <= 1, got 51"):
        linear_phase_lowpass(RADII, _angles(PRINTED_PI), 12)
    taps = linear_phase_lowpass(RADII, _angles(PRINTED_PI), 12, require_lowpass=False)
    assert abs(response(taps, [1.0], 50.0, T_S)[0]) == pytest.approx(0.43, abs=0.01)
    assert abs(response(taps, [1.0], 499.999, T_S)[0]) > 10.0


@pytest.mark.parametrize("axis", ["x", "y"])
@pytest.mark.parametrize("f_d_hz", [20.0, 50.0, 120.0, 200.0])
@pytest.mark.parametrize("spare_dof", ["zero_dc", "rls"])
def test_h_times_model_is_one_at_fd(axis: str, f_d_hz: float, spare_dof: str) -> None:
    design = design_pdc(PAPER002_MODELS[axis], f_d_hz, RADII, _angles(NEGATED_PI), 12, 3, spare_dof)
    assert abs(design.hp_at_fd) == pytest.approx(1.0, abs=0.01)
    assert math.degrees(np.angle(design.hp_at_fd)) == pytest.approx(0.0, abs=1.0)
    model = PAPER002_MODELS[axis]
    independent = response(design.h, [1.0], f_d_hz, T_S)[0] * response(model.numerator, model.denominator,
                                                                        f_d_hz, T_S)[0]
    assert independent == pytest.approx(design.hp_at_fd)


@pytest.mark.parametrize("axis", ["x", "y"])
def test_papers_w_is_the_fit_without_ml(axis: str) -> None:
    """The paper's W inverts z^-6 P_n (M_L left out): H·P_n at f_d is then M_L, not 1."""
    model = PAPER002_MODELS[axis]
    ours = design_pdc(model, 50.0, RADII, _angles(NEGATED_PI), 12, 3, "rls", include_ml=False)
    assert_allclose(ours.w, PAPER_W[axis], atol=0.2)  # x: 9.948 -21.922 11.308; y: 13.176 -29.676 15.845
    lowpass = np.array(ours.lowpass)
    paper_hp = (response(np.convolve(lowpass, PAPER_W[axis]), [1.0], 50.0, T_S)[0]
                * response(model.numerator, model.denominator, 50.0, T_S)[0])
    assert abs(paper_hp) == pytest.approx(ours.magnitude_ml, rel=0.01)  # ≈ 0.69: about 69 % removal in theory
    with_ml = design_pdc(model, 50.0, RADII, _angles(NEGATED_PI), 12, 3, "rls", include_ml=True)
    assert abs(with_ml.hp_at_fd) == pytest.approx(1.0, abs=0.001)


def test_zero_dc_spends_the_spare_degree_of_freedom() -> None:
    design = design_pdc(PAPER002_MODELS["x"], 50.0, RADII, _angles(NEGATED_PI), 12, 3, "zero_dc")
    assert sum(design.w) == pytest.approx(0.0, abs=1e-9)
    rls = design_pdc(PAPER002_MODELS["x"], 50.0, RADII, _angles(NEGATED_PI), 12, 3, "rls")
    assert abs(sum(rls.w)) > 0.1  # the RLS start leaves DC action


def test_rls_recursion_is_the_regularised_least_squares() -> None:
    """R(0) = I/δ, W(0) = 0: the recursion ends at (δI + Σ X Xᵀ)⁻¹ Σ X s."""
    rng = np.random.default_rng(5)
    x, s, delta = rng.normal(size=200), rng.normal(size=200), 0.3
    regressors = np.column_stack([np.concatenate((np.zeros(k), x[:len(x) - k])) for k in range(3)])
    expected = np.linalg.solve(delta * np.eye(3) + regressors.T @ regressors, regressors.T @ s)
    assert_allclose(rls_fit(x, s, 3, delta), expected, rtol=1e-8)


def test_q_filter_uses_binomial_coefficients() -> None:
    num, den = q_filter_continuous(4, 2, 0.01)
    assert_allclose(den, np.poly([-100.0] * 4) * 0.01 ** 4)  # (1 + τs)^4
    assert_allclose(num[::-1], [comb(4, k) * 0.01 ** k for k in range(3)])
    b, a = q_filter(4, 2, 0.01, PAPER002_MODELS["x"])
    assert b[0] == 0.0  # strictly proper like the model (one sample of delay)
    assert sum(b) / sum(a) == pytest.approx(1.0)


def test_q_relative_degree_below_the_models_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"q_relative_degree must be >= 1 \(the model's relative degree\), got 0"):
        q_filter(3, 0, 0.005, PAPER002_MODELS["x"])


def test_mbda_pi_is_the_backward_difference() -> None:
    b, a = mbda_pi(2.0, 50.0, T_S)
    step = signal.lfilter(b, a, np.ones(5))
    assert_allclose(step, 2.0 + 50.0 * T_S * np.arange(1, 6))


@pytest.mark.parametrize("law, params, message", [
    ("pdc", {"spindle_rpm": 2500.0, "flutes": 12}, r"f_d_hz must be in \(0, 500\) Hz .* got 500"),
    ("pdc", {"spindle_rpm": 15000.0}, r"pdc.spindle_rpm must be in \[1.0, 9000.0\], got 15000"),
    ("pdc", {"filter_order": 11}, "filter_order must be even, got 11"),
    ("pdc", {"filter_order": 8}, "filter_order 8 needs 2 zeros"),
    ("pdc", {"zero_radii": [0.9, 1.2, 0.85]}, r"zero_radii\[1\] must be in \(0, 1\).*got 1.2"),
    ("pdc", {"zero_angles_pi": list(PRINTED_PI)}, "no low-pass"),
    ("pdc", {"spare_dof": "rls", "spindle_rpm": 2333.0, "flutes": 12}, "RLS for W did not converge.*f_d_hz 466.6"),
    ("pdc", {"spare_dof": "best"}, "spare_dof must be one of"),
    ("pdc", {"zero_radii": [0.9, "a", 0.85]}, r"pdc.zero_radii\[1\] must be a number, got 'a'"),
    ("pdc", {"zero_angles_pi": 0.3}, "pdc.zero_angles_pi must be a list of numbers, got 0.3"),
    ("dob", {"q_relative_degree": 0}, r"q_relative_degree must be in \[1, 3\], got 0"),
    ("dob", {"q_order": 2, "q_relative_degree": 3}, "q_relative_degree must be <= q_order 2, got 3"),
    ("dob_pdc", {"model": "z"}, "model must be one of"),
])
def test_bad_designs_are_refused(law: str, params: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        law_config(law, params)
