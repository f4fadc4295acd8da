"""Feed-drive axis: exact ZOH integration against scipy, steady state, stiction, faults."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_plant_sim.models.axis import AxisConfig, FeedDriveAxis, dynamics

BLU_M = 1e-5
X_AXIS = {"name": "x", "gain_blu_s_per_dac": 28.35, "time_constant_s": 0.055,
          "friction": "paper000_x"}


def make_axis(**overrides: object) -> FeedDriveAxis:
    return FeedDriveAxis(AxisConfig.from_mapping({**X_AXIS, **overrides}))


def reference_trajectory(axis: FeedDriveAxis, x0: list[float], commands: list[float],
                         dt_s: float) -> np.ndarray:
    """solve_ivp on ``dynamics`` with the command held over each period; states (n+1, 2)."""
    states = [np.array(x0, dtype=float)]
    for u in commands:
        sol = solve_ivp(dynamics, (0.0, dt_s), states[-1], method="DOP853",
                        args=(u, axis.params), rtol=1e-12, atol=1e-9)
        states.append(sol.y[:, -1])
    return np.array(states)


def stepped_trajectory(axis: FeedDriveAxis, x0: list[float], commands: list[float],
                       dt_s: float) -> np.ndarray:
    axis.reset(x0[0] * BLU_M, x0[1] * BLU_M)
    states = [[axis.position_blu, axis.velocity_blu_s]]
    for u in commands:
        axis.step(u, dt_s)
        states.append([axis.position_blu, axis.velocity_blu_s])
    return np.array(states)


SMOOTH_CASES = [
    pytest.param({"friction": "none"}, [0.0, 0.0], id="none-from-rest"),
    pytest.param({"friction": "coulomb_viscous",
                  "friction_params": {"viscous_dac_per_mm_s": 2.0}}, [100.0, -300.0], id="viscous"),
    pytest.param({"friction": "coulomb_viscous",
                  "friction_params": {"coulomb_dac": 8.0, "viscous_dac_per_mm_s": 0.7}},
                 [0.0, 2500.0], id="coulomb-viscous-no-reversal"),
]


@pytest.mark.parametrize(("overrides", "x0"), SMOOTH_CASES)
def test_step_matches_solve_ivp(overrides: dict, x0: list[float]) -> None:
    axis = make_axis(**overrides)
    commands = [40.0, 55.0, 30.0, 80.0, 60.0] * 4
    expected = reference_trajectory(axis, x0, commands, 0.01)
    actual = stepped_trajectory(axis, x0, commands, 0.01)
    assert_allclose(actual, expected, rtol=1e-9, atol=1e-7)


@settings(max_examples=40, deadline=None)
@given(u=st.floats(-120, 120), v0=st.floats(-3000, 3000), dt_s=st.floats(1e-4, 0.05),
       substeps=st.integers(2, 9))
def test_substeps_do_not_change_an_exact_step(u: float, v0: float, dt_s: float, substeps: int) -> None:
    params = {"friction": "coulomb_viscous", "friction_params": {"viscous_dac_per_mm_s": 1.5}}
    one, many = make_axis(**params), make_axis(**params, substeps=substeps)
    for axis in (one, many):
        axis.reset(0.0, v0 * BLU_M)
        axis.step(u, dt_s)
    assert_allclose([many.position_blu, many.velocity_blu_s],
                    [one.position_blu, one.velocity_blu_s], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize(("command", "friction_dac"), [(80.0, 13.95), (-80.0, -11.84), (120.0, 13.95)])
def test_steady_state_velocity_is_k_times_net(command: float, friction_dac: float) -> None:
    axis = make_axis()
    for _ in range(200):
        axis.step(command, 0.01)
    assert_allclose(axis.velocity_blu_s, 28.35 * (command - friction_dac), rtol=1e-9)
    assert_allclose(axis.velocity_m_s, 28.35 * (command - friction_dac) * BLU_M, rtol=1e-9)
    assert axis.friction_force == friction_dac


@pytest.mark.parametrize("command", [0.0, 15.0, -15.0, 20.49, -18.27])
def test_stopped_axis_stays_within_breakaway(command: float) -> None:
    axis = make_axis()
    axis.reset(0.002, 0.0)
    for _ in range(50):
        axis.step(command, 0.01)
    assert axis.position_m == 0.002
    assert axis.velocity_m_s == 0.0
    assert axis.friction_force == command


@pytest.mark.parametrize(("command", "sign"), [(20.6, 1.0), (-18.4, -1.0)])
def test_command_beyond_breakaway_starts_motion(command: float, sign: float) -> None:
    axis = make_axis()
    axis.step(command, 0.01)
    assert np.sign(axis.velocity_m_s) == sign
    assert np.sign(axis.position_m) == sign


def test_moving_axis_stops_at_the_analytic_time_and_sticks() -> None:
    k, tau, fc, v0 = 28.35, 0.055, 10.0, 2000.0
    axis = make_axis(friction="coulomb_viscous", friction_params={"coulomb_dac": fc})
    axis.reset(0.0, v0 * BLU_M)
    axis.step(0.0, 0.2)  # the crossing is at t* = 0.115 s
    decay = k * fc / (v0 + k * fc)  # e^{-t*/tau} at the zero crossing
    t_stop = -tau * math.log(decay)
    p_stop = (v0 + k * fc) * tau * (1.0 - decay) - k * fc * t_stop
    assert axis.velocity_blu_s == 0.0
    assert_allclose(axis.position_blu, p_stop, rtol=1e-12)
    axis.step(0.0, 0.1)
    assert axis.velocity_blu_s == 0.0
    assert_allclose(axis.position_blu, p_stop, rtol=1e-12)


def test_reversal_passes_through_zero_onto_the_other_branch() -> None:
    axis = make_axis()
    axis.reset(0.0, 0.01)
    velocities = []
    for _ in range(200):
        axis.step(-80.0, 0.01)
        velocities.append(axis.velocity_blu_s)
    assert velocities[0] > 0.0 > velocities[-1]
    assert_allclose(velocities[-1], 28.35 * (-80.0 + 11.84), rtol=1e-9)


@settings(max_examples=40, deadline=None)
@given(u=st.floats(-11.0, 11.0), v0_mm_s=st.floats(-100.0, 100.0))
def test_small_command_always_stops_the_axis(u: float, v0_mm_s: float) -> None:
    axis = make_axis(friction="paper000_y")
    axis.reset(0.0, v0_mm_s * 1e-3)
    for _ in range(100):
        axis.step(u, 0.01)
    assert axis.stopped
    assert axis.friction_force == u


def test_dynamics_holds_a_stuck_axis_and_breaks_away() -> None:
    axis = make_axis()
    assert_allclose(dynamics(0.0, [5.0, 0.0], 10.0, axis.params), [0.0, 0.0])
    assert_allclose(dynamics(0.0, [5.0, 0.0], 30.0, axis.params),
                    [0.0, 28.35 * (30.0 - 20.49) / 0.055])
    v_mm_s = -1.0
    force = -0.04 * v_mm_s**2 - 1.00 * v_mm_s - 18.27
    assert_allclose(dynamics(0.0, [5.0, -100.0], 0.0, axis.params),
                    [-100.0, (28.35 * (0.0 - force) + 100.0) / 0.055])


def test_command_limit_saturates_the_drive() -> None:
    limited, free = make_axis(command_limit_dac=50.0), make_axis()
    limited.step(200.0, 0.05)
    free.step(50.0, 0.05)
    assert limited.position_blu == free.position_blu


@pytest.mark.parametrize("command", [math.nan, math.inf, -math.inf, "fast"])
def test_non_finite_command_is_a_fault_and_keeps_the_state(command: object) -> None:
    axis = make_axis()
    axis.step(60.0, 0.01)
    before = (axis.position_m, axis.velocity_m_s, axis.friction_force)
    with pytest.raises(FaultError) as info:
        axis.step(command, 0.01)  # type: ignore[arg-type]  # a bad command on purpose
    assert "axis x" in str(info.value)
    assert repr(command) in str(info.value)
    assert (axis.position_m, axis.velocity_m_s, axis.friction_force) == before


@pytest.mark.parametrize("dt_s", [0.0, -0.01, math.nan])
def test_bad_period_is_a_fault(dt_s: float) -> None:
    with pytest.raises(FaultError, match="dt_s must be finite and > 0"):
        make_axis().step(10.0, dt_s)


@pytest.mark.parametrize(("key", "value", "message"), [
    ("time_constant_s", -1, "time_constant_s must be > 0, got -1"),
    ("gain_blu_s_per_dac", 0, "gain_blu_s_per_dac must be > 0, got 0"),
    ("blu_m", math.nan, "blu_m must be finite, got nan"),
    ("substeps", 0, "substeps must be an integer >= 1, got 0"),
    ("substeps", 2.5, "substeps must be an integer >= 1, got 2.5"),
    ("command_limit_dac", -5, "command_limit_dac must be > 0, got -5"),
    ("friction_scale", -0.5, "friction_scale must be >= 0, got -0.5"),
    ("friction", "sticky", "friction must be one of"),
    ("friction_params", {"scale": -1}, "scale must be >= 0, got -1"),
    ("name", "", "name must be a non-empty string, got ''"),
])
def test_bad_config_names_option_bound_value(key: str, value: object, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        AxisConfig.from_mapping({**X_AXIS, key: value})
    assert message in str(info.value)


def test_unknown_config_key_lists_valid_keys() -> None:
    with pytest.raises(ConfigError) as info:
        AxisConfig.from_mapping({**X_AXIS, "gain": 3.0})
    assert "axis.gain: unknown key" in str(info.value)
    assert "gain_blu_s_per_dac" in str(info.value)


def test_reset_sets_si_state() -> None:
    axis = make_axis()
    axis.reset(0.123, -0.004)
    assert_allclose([axis.position_blu, axis.velocity_blu_s], [12300.0, -400.0])
    assert axis.friction_force == 0.0
    with pytest.raises(FaultError, match="position_m must be finite"):
        axis.reset(math.nan)
