"""Paper 003's analytic model: Eq. 1's ζ, ω_n, Eqs. 8, 13, 15, the loop's rise time and margins."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import signal

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.tuning import paper003_model as p3


@pytest.mark.parametrize("column", ["standard", "optimal"])
def test_zeta_and_omega_from_k1_k2_match_table_2(column: str) -> None:
    row = p3.PAPER003_TABLE[column]
    model = p3.model_of_column(column)
    assert_allclose(model.omega_n_rad_s, row.omega_n_rad_s, rtol=0.005)
    assert_allclose(model.zeta, row.zeta, rtol=0.005)


def test_velocity_loop_poles_are_the_second_order_ones() -> None:
    model = p3.model_of_column("optimal")
    poles = np.sort(np.real(p3.velocity_loop(model).poles()))
    z, w = model.zeta, model.omega_n_rad_s
    assert_allclose(poles, np.sort([-w * (z + math.sqrt(z * z - 1)), -w * (z - math.sqrt(z * z - 1))]), rtol=1e-9)


def test_eq15_is_the_phase_margin_of_the_standard_second_order_loop() -> None:
    import control

    for zeta in (0.3, 0.71, 1.63):
        open_loop = control.tf([1.0], [1.0, 2.0 * zeta, 0.0])  # ω_n = 1
        _, pm, *_ = control.stability_margins(open_loop)
        assert_allclose(p3.phase_margin_eq15_deg(zeta), pm, atol=0.05)


@pytest.mark.parametrize("zeta", [0.2, 0.5])
def test_resonance_peak_of_a_second_order_system(zeta: float) -> None:
    """M_r = 1 / (2ζ√(1 − ζ²)) for ω_n² / (s² + 2ζω_n s + ω_n²)."""
    import control

    system = control.tf([100.0], [1.0, 20.0 * zeta, 100.0])
    expected = 1.0 / (2.0 * zeta * math.sqrt(1.0 - zeta ** 2))
    assert_allclose(p3.resonance_peak_db(system), 20.0 * math.log10(expected), atol=0.01)


def test_resonance_peak_grows_with_the_position_gain() -> None:
    low = p3.closed_resonance_peak_db(p3.Paper003Model(position_gain_x_1_s=20.0, position_gain_y_1_s=20.0))
    high = p3.closed_resonance_peak_db(p3.Paper003Model(position_gain_x_1_s=200.0, position_gain_y_1_s=200.0))
    assert high > low >= 0.0


def test_mismatch_and_interpolation_errors_by_hand() -> None:
    model = p3.Paper003Model(position_gain_x_1_s=30.0, position_gain_y_1_s=25.0, t_ip_s=0.01)
    feed_m_s, radius_m = 0.1, 0.005
    assert_allclose(p3.mismatch_error_m(model, feed_m_s), 0.5 * 0.1 * (1 / 25 - 1 / 30))
    assert_allclose(p3.interpolation_error_m(model, feed_m_s, radius_m, "exponential"), 1e-4 * 0.01 / 0.01)
    linear = p3.interpolation_error_m(model, feed_m_s, radius_m, "linear")
    assert_allclose(linear * 12.0, p3.interpolation_error_m(model, feed_m_s, radius_m, "exponential"))


def test_pi_loop_leaves_no_steady_lag() -> None:
    """1 − H = s² / den: the position error to a velocity step, (1 − H)/s², is 1/den's impulse: it decays to 0."""
    model = p3.model_of_column("standard")
    den = [1.0, model.torque_per_inertia * model.k2, model.torque_per_inertia * model.k1]
    t = np.linspace(0.0, 0.5, 2001)
    _, position_error = signal.impulse(signal.lti([1.0], den), T=t)
    assert abs(position_error).max() > 0.0
    assert abs(position_error[-1]) < 1e-6 * abs(position_error).max()
    assert p3.LAG_READINGS["pi_exact"](model) == 0.0


def test_rise_time_measured_on_the_loop_matches_scipy() -> None:
    model = p3.model_of_column("standard")
    c = model.torque_per_inertia
    t = np.linspace(0.0, 0.1, 20001)
    _, y = signal.step(signal.lti([c * model.k2, c * model.k1], [1.0, c * model.k2, c * model.k1]), T=t)
    rise = t[np.argmax(y >= 0.9)] - t[np.argmax(y >= 0.1)]
    assert_allclose(p3.rise_time_velocity_loop_s(model), rise, rtol=0.02)


@pytest.mark.parametrize("gain_1_s", [10.0, 30.0, 150.0])
def test_margins_polynomial_method_agrees_with_frequency_response(gain_1_s: float) -> None:
    import control

    model = p3.Paper003Model(position_gain_x_1_s=gain_1_s, position_gain_y_1_s=gain_1_s)
    gm, pm, *_ = control.stability_margins(p3.position_open_loop(model), method="frd")
    assert_allclose(p3.margins(model), (pm, 20.0 * math.log10(gm)), rtol=1e-4)


def test_margins_fall_with_a_larger_position_gain() -> None:
    low = p3.margins(p3.Paper003Model(position_gain_x_1_s=20.0, position_gain_y_1_s=20.0))
    high = p3.margins(p3.Paper003Model(position_gain_x_1_s=200.0, position_gain_y_1_s=200.0))
    assert high[0] < low[0] and high[1] < low[1]


def test_grid_shape_and_direction_symmetry() -> None:
    errors = p3.grid_errors_um(p3.model_of_column("standard"), p3.Readings(lag="envelope"))
    assert errors.shape == (3, 4, 2)
    assert_allclose(errors[..., 0], errors[..., 1])
    assert np.all(np.diff(errors, axis=0) > 0)  # a larger feed, a larger error


def test_bad_reading_and_model_refused_by_name() -> None:
    with pytest.raises(ConfigError, match="lag"):
        p3.Readings(lag="nonsense")
    with pytest.raises(ConfigError, match="k1"):
        p3.Paper003Model(k1=-1.0)


def test_loop_radius_error_of_a_fast_velocity_loop_is_the_first_order_one() -> None:
    """With ω_n ≫ k the loop is k/(s + k): the circle keeps R k / √(k² + ω²)."""
    model = p3.Paper003Model(k1=1.0e6, k2=2.0e3, position_gain_x_1_s=30.0, position_gain_y_1_s=30.0)
    feed_m_s, radius_m = 8000.0 / 60000.0, 0.003
    omega = feed_m_s / radius_m
    expected = radius_m * (1.0 - 30.0 / math.hypot(30.0, omega))
    assert_allclose(p3.loop_radius_error_m(model, feed_m_s, radius_m), expected, rtol=1e-3)


def test_table_2_columns_barely_change_the_loops_radius_error() -> None:
    """The issue's claim: K1, K2 move the physical radius error by little (here < 5 % at k = 30 /s)."""
    base = p3.Paper003Model(position_gain_x_1_s=30.0, position_gain_y_1_s=30.0)
    std, opt = (p3.loop_grid_error_um(p3.model_of_column(c, base)) for c in ("standard", "optimal"))
    assert abs(opt / std - 1.0) < 0.05
    assert std > 0.0
