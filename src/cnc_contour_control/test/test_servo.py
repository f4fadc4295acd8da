"""Servo controller: composition, saturation, quantisation, faults, config, closed loop."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.errors import ConfigError, FaultError
from cnc_contour_control.laws import LAWS
from cnc_contour_control.servo import ServoConfig, ServoController, ServoOutput, quantise


def servo(**overrides: object) -> ServoController:
    return ServoController(ServoConfig.from_mapping({"axis_name": "x", **overrides}))


def p_servo(**overrides: object) -> ServoController:
    return servo(law="p", law_params={"kp": 1.0}, **overrides)


def test_defaults_are_paper000() -> None:
    config = ServoConfig(axis_name="x")
    assert (config.law, config.counts_per_m, config.output_limit, config.quantum) == \
        ("pid", 1e5, 127.0, 1.0)
    assert config.command_unit == "dac"


def test_output_is_the_sum_of_its_parts() -> None:
    ctrl = servo(law="p", law_params={"kp": 2.0}, ff1=0.5, ff2=0.01, quantum=0, output_limit=1e6)
    out = ctrl.step(0.01, ref_position_m=1e-4, ref_velocity_m_s=1e-3,
                    ref_acceleration_m_s2=1e-2, position_m=0.0, compensation=3.0)
    # error 10 BLU -> fb 20; ff1·100 BLU/s = 50; ff2·1000 BLU/s² = 10
    assert_allclose([out.feedback, out.feedforward, out.compensation, out.command],
                    [20.0, 60.0, 3.0, 83.0])
    assert_allclose(out.error_m, 1e-4)
    assert out.disturbance_estimate == 0.0
    assert out.saturated is False
    assert isinstance(out, ServoOutput)


@pytest.mark.parametrize(("error_blu", "command", "saturated"), [
    (2.5, 3.0, False), (-2.5, -3.0, False), (2.49, 2.0, False), (0.5, 1.0, False),
    (-0.4, 0.0, False), (126.6, 127.0, False), (126.9, 127.0, False),
    (130.0, 127.0, True), (-500.0, -127.0, True),
])
def test_saturation_and_quantisation_8bit(error_blu: float, command: float, saturated: bool) -> None:
    out = p_servo().step(0.01, error_blu * 1e-5, 0.0, 0.0, 0.0)
    assert out.command == command
    assert out.saturated is saturated
    assert_allclose(out.feedback, error_blu)


@pytest.mark.parametrize(("limit", "quantum", "error_blu", "command"), [
    (127.5, 1.0, 127.4, 127.0),
    (127.5, 1.0, 300.0, 127.0),  # 127.5 would round to 128 > limit: one quantum back
    (10.0, 0.25, 3.13, 3.25),
    (10.0, 0.25, -3.12, -3.0),
    (10.0, 0.0, 3.1234, 3.1234),
])
def test_quantum_and_limit_combinations(limit: float, quantum: float, error_blu: float,
                                        command: float) -> None:
    out = p_servo(output_limit=limit, quantum=quantum).step(0.01, error_blu * 1e-5, 0.0, 0.0, 0.0)
    assert_allclose(out.command, command, rtol=1e-12)
    assert abs(out.command) <= limit


@pytest.mark.parametrize(("value", "quantum", "expected"), [
    (0.5, 1.0, 1.0), (-0.5, 1.0, -1.0), (1.5, 1.0, 2.0), (-1.49, 1.0, -1.0),
    (0.75, 0.5, 1.0), (0.74, 0.5, 0.5), (7.7, 0.0, 7.7), (-0.2, 1.0, 0.0),
])
def test_quantise_rounds_half_away_from_zero(value: float, quantum: float, expected: float) -> None:
    assert_allclose(quantise(value, quantum), expected)


@pytest.mark.parametrize("index", range(6))
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_input_is_a_fault_naming_it(index: int, bad: float) -> None:
    names = ["dt_s", "ref_position_m", "ref_velocity_m_s", "ref_acceleration_m_s2",
             "position_m", "compensation"]
    args = [0.01, 1e-4, 0.0, 0.0, 0.0, 0.0]
    args[index] = bad
    ctrl = servo()
    with pytest.raises(FaultError) as info:
        ctrl.step(*args)
    assert f"servo x: {names[index]} must be finite, got {bad!r}" in str(info.value)
    assert ctrl.step(0.01, 1e-5, 0.0, 0.0, 0.0).feedback == pytest.approx(9.2)  # state untouched


def test_non_positive_period_is_a_fault() -> None:
    with pytest.raises(FaultError, match="dt_s must be > 0, got 0.0"):
        servo().step(0.0, 0.0, 0.0, 0.0, 0.0)


def test_reset_resets_the_law() -> None:
    ctrl = servo()
    first = ctrl.step(0.01, 1e-5, 0.0, 0.0, 0.0)
    ctrl.step(0.01, 3e-5, 0.0, 0.0, 0.0)
    ctrl.reset()
    assert ctrl.step(0.01, 1e-5, 0.0, 0.0, 0.0) == first


@pytest.mark.parametrize(("key", "value", "message"), [
    ("counts_per_m", 0, "counts_per_m must be > 0, got 0"),
    ("output_limit", -1, "output_limit must be > 0, got -1"),
    ("quantum", -0.5, "quantum must be >= 0, got -0.5"),
    ("ff1", math.nan, "ff1 must be finite, got nan"),
    ("ff2", "a lot", "ff2 must be a number, got 'a lot'"),
    ("axis_name", "", "axis_name must be a non-empty string, got ''"),
    ("law", "bang_bang", f"law must be one of {sorted(LAWS)}, got 'bang_bang'"),
    ("law_params", {"kp": -2}, "pid.kp must be >= 0, got -2"),
    ("law_params", {"gain": 2}, "pid.gain: unknown key; valid keys are"),
    ("law_params", [1, 2], "law_params must be a mapping, got [1, 2]"),
])
def test_bad_config_names_option_bound_value(key: str, value: object, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        ServoConfig.from_mapping({"axis_name": "x", key: value})
    assert message in str(info.value)


def test_unknown_config_key_lists_valid_keys() -> None:
    with pytest.raises(ConfigError) as info:
        ServoConfig.from_mapping({"axis_name": "x", "kp": 2.0})
    assert "servo.kp: unknown key; valid keys are ['axis_name', 'command_unit', 'counts_per_m'" \
        in str(info.value)



# ---------------------------------------------------------------- closed loop with the plant
# Eq. (1) of paper 000 for P control of K/(s(τs+1)) on (u − F_d) under a ramp V_r:
#   e_ss = V_r/(K·K_e·K_p) + F_d/K_p.
# With K in BLU/s per DAC unit, V_r in BLU/s, e in BLU and u in DAC units, K_e = 1
# (the controller output already is the DAC value; the digest's check "667 BLU/s needs
# 23.5 DAC units" = 666.7/28.35 confirms it). F_d is Eq. (15) at V_r in mm/s.

V_R_M_S = 0.4 / 60.0  # 0.4 m/min
T_S = 0.01


def track_ramp(law: str, law_params: dict, quantum: float, duration_s: float = 6.0) -> np.ndarray:
    """Following error [BLU] of the nominal paper-000 X axis tracking a ramp from rest."""
    from cnc_plant_sim.plant import make_plant  # the plant package is a test-only dependency

    plant = make_plant({"axes": ["x"], "variation": {"gain_pct": 0, "time_constant_pct": 0,
                                                     "friction_pct": 0}})
    ctrl = servo(law=law, law_params=law_params, quantum=quantum)
    errors = []
    for k in range(int(round(duration_s / T_S))):
        out = ctrl.step(T_S, V_R_M_S * k * T_S, V_R_M_S, 0.0, plant.positions_m()[0])
        plant.step([out.command], T_S)
        errors.append(out.error_m * 1e5)
    return np.array(errors)


def eq1_error_blu(kp: float) -> float:
    k, k_e = 28.35, 1.0
    v_blu_s, v_mm_s = V_R_M_S * 1e5, V_R_M_S * 1e3
    friction_dac = 0.05 * v_mm_s**2 - 1.16 * v_mm_s + 20.49  # Eq. (15), X, 0 <= V < 12
    return v_blu_s / (k * k_e * kp) + friction_dac / kp  # = 9.80 + 6.24 = 16.04 BLU


def test_p_control_steady_error_matches_eq1() -> None:
    errors = track_ramp("p", {"kp": 2.4}, quantum=0.0)
    assert_allclose(errors[-100:], eq1_error_blu(2.4), rtol=1e-6)


def test_p_control_with_8bit_dac_stays_near_eq1() -> None:
    steady = track_ramp("p", {"kp": 2.4}, quantum=1.0)[-200:]
    assert abs(steady.mean() - eq1_error_blu(2.4)) < 0.1
    assert np.ptp(steady) < 1.0  # quantisation ripple of about ±0.5 DAC / Kp


def test_pid_tracks_the_ramp_with_bounded_error() -> None:
    errors = track_ramp("pid", {}, quantum=1.0)
    assert np.abs(errors).max() < 2.0 * eq1_error_blu(2.4)  # start-up from stiction, ~18 BLU
    assert np.abs(errors[-200:]).max() < 0.5  # the integral removes Eq. (1)'s error
