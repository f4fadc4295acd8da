"""Servo controller: composition, the law seam, saturation, quantisation, faults, config, retune, closed loop."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.axis.servo import ServoConfig, ServoController, ServoOutput, quantise
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.laws import LAWS, LawEntry, LawOutput, LawSample
from cnc_contour_control.laws.pid import PConfig


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
                    ref_acceleration_m_s2=1e-2, position_m=0.0, velocity_m_s=0.0, compensation=3.0)
    # error 10 BLU -> fb 20; ff1·100 BLU/s = 50; ff2·1000 BLU/s² = 10
    assert_allclose([out.feedback, out.feedforward, out.compensation, out.command],
                    [20.0, 60.0, 3.0, 83.0])
    assert_allclose(out.error_m, 1e-4)
    assert out.disturbance_estimate == 0.0
    assert out.saturated is False
    assert isinstance(out, ServoOutput)


@pytest.mark.parametrize(("error_blu", "command", "saturated"), [
    (2.5, 3.0, False), (-2.5, -3.0, False), (2.49, 2.0, False), (0.5, 1.0, False),
    (-0.4, 0.0, False), (126.4, 126.0, False),
    (126.6, 127.0, True), (126.9, 127.0, True),  # rounded onto the limit: the applied command is at it
    (127.0, 127.0, True), (130.0, 127.0, True), (-500.0, -127.0, True),
])
def test_saturation_and_quantisation_8bit(error_blu: float, command: float, saturated: bool) -> None:
    out = p_servo().step(0.01, error_blu * 1e-5, 0.0, 0.0, 0.0, 0.0, 0.0)
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
    out = p_servo(output_limit=limit, quantum=quantum).step(0.01, error_blu * 1e-5, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert_allclose(out.command, command, rtol=1e-12)
    assert abs(out.command) <= limit


@pytest.mark.parametrize(("value", "quantum", "expected"), [
    (0.5, 1.0, 1.0), (-0.5, 1.0, -1.0), (1.5, 1.0, 2.0), (-1.49, 1.0, -1.0),
    (0.75, 0.5, 1.0), (0.74, 0.5, 0.5), (7.7, 0.0, 7.7), (-0.2, 1.0, 0.0),
])
def test_quantise_rounds_half_away_from_zero(value: float, quantum: float, expected: float) -> None:
    assert_allclose(quantise(value, quantum), expected)


@pytest.mark.parametrize(("value", "quantum", "limit", "expected"), [
    (300.0, 1.0, 127.5, 127.0),  # clipped to 127.5, which rounds to 128 > limit: one quantum back
    (-127.5, 1.0, 127.5, -127.0), (127.4, 1.0, 127.5, 127.0), (200.0, 1.0, 127.0, 127.0),
    (-9.99, 0.25, 10.0, -10.0), (3.13, 0.25, 10.0, 3.25), (12.0, 0.0, 10.0, 10.0), (-0.3, 0.0, 0.1, -0.1),
])
def test_quantise_never_goes_beyond_the_limit(value: float, quantum: float, limit: float,
                                              expected: float) -> None:
    assert quantise(value, quantum, limit) == pytest.approx(expected, rel=1e-12)
    assert abs(quantise(value, quantum, limit)) <= limit


def test_the_servo_runs_the_tested_quantiser(monkeypatch: pytest.MonkeyPatch) -> None:
    import cnc_contour_control.axis.servo as servo_module

    calls = []
    monkeypatch.setattr(servo_module, "quantise", lambda *args: calls.append(args) or 42.0)
    out = p_servo(output_limit=100.0, quantum=0.5).step(0.01, 3e-5, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert out.command == 42.0 and calls == [(pytest.approx(3.0), 0.5, 100.0)]


@pytest.mark.parametrize("index", range(7))
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_input_is_a_fault_naming_it(index: int, bad: float) -> None:
    names = ["dt_s", "ref_position_m", "ref_velocity_m_s", "ref_acceleration_m_s2",
             "position_m", "velocity_m_s", "compensation"]
    args = [0.01, 1e-4, 0.0, 0.0, 0.0, 0.0, 0.0]
    args[index] = bad
    ctrl = servo()
    with pytest.raises(FaultError) as info:
        ctrl.step(*args)
    assert f"servo x: {names[index]} must be finite, got {bad!r}" in str(info.value)
    assert ctrl.step(0.01, 1e-5, 0.0, 0.0, 0.0, 0.0, 0.0).feedback == pytest.approx(9.2)  # state untouched


def test_old_call_without_velocity_and_compensation_fails_loudly() -> None:
    with pytest.raises(TypeError):
        servo().step(0.01, 1e-4, 0.0, 0.0, 0.0, 3.0)  # type: ignore[call-arg]  # the old signature on purpose


def test_non_positive_period_is_a_fault() -> None:
    with pytest.raises(FaultError, match="dt_s must be > 0, got 0.0"):
        servo().step(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def test_reset_resets_the_law() -> None:
    ctrl = servo()
    first = ctrl.step(0.01, 1e-5, 0.0, 0.0, 0.0, 0.0, 0.0)
    ctrl.step(0.01, 3e-5, 0.0, 0.0, 0.0, 0.0, 0.0)
    ctrl.reset()
    assert ctrl.step(0.01, 1e-5, 0.0, 0.0, 0.0, 0.0, 0.0) == first


class RecordingLaw:
    """A law that keeps a copy of every sample it sees and answers with a disturbance estimate."""

    def __init__(self, config: PConfig) -> None:
        self.config, self.seen, self.output = config, [], LawOutput()

    def reset(self) -> None:
        self.seen.clear()

    def retune(self, config: PConfig) -> None:
        self.config = config

    def step(self, sample: LawSample) -> LawOutput:
        self.seen.append({name: getattr(sample, name) for name in LawSample.__slots__})
        self.output.feedback, self.output.disturbance_estimate = 100.0 * sample.error_counts, -2.5
        return self.output


@pytest.fixture()
def recording_law() -> None:  # type: ignore[misc]  # a yield fixture
    LAWS["recording"] = LawEntry(PConfig, RecordingLaw)
    yield
    del LAWS["recording"]


@pytest.mark.usefixtures("recording_law")
def test_the_law_sees_the_sample_in_counts_and_the_applied_command() -> None:
    ctrl = servo(law="recording", ff1=0.0, output_limit=127.0, quantum=1.0)
    first = ctrl.step(0.01, 2e-5, 1e-3, 2e-2, 1e-5, 5e-4, 0.0)  # error 1 BLU -> feedback 100
    second = ctrl.step(0.004, 2e-5, 0.0, 0.0, 1.9966e-5, 0.0, 0.3)  # 0.0034 BLU -> 0.34 + 0.3 -> 1
    seen = ctrl.law.seen
    assert seen[0] == pytest.approx({"dt_s": 0.01, "error_counts": 1.0, "position_counts": 1.0,
                                     "velocity_counts_s": 50.0, "ref_velocity_counts_s": 100.0,
                                     "ref_acceleration_counts_s2": 2000.0, "applied_command": 0.0})
    assert (first.command, first.saturated, first.feedback) == (100.0, False, pytest.approx(100.0))
    assert seen[1]["applied_command"] == first.command  # after saturation and quantisation
    assert seen[1]["dt_s"] == 0.004
    assert second.command == 1.0 and second.disturbance_estimate == -2.5
    ctrl.reset()
    ctrl.step(0.01, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert seen[-1]["applied_command"] == 0.0


def test_retune_keeps_the_law_state_and_takes_the_new_gains() -> None:
    ctrl, twin = servo(), servo()
    for ref in (1e-5, 2e-5, 4e-5):
        ctrl.step(0.01, ref, 0.0, 0.0, 0.0, 0.0, 0.0)
        twin.step(0.01, ref, 0.0, 0.0, 0.0, 0.0, 0.0)
    ctrl.retune(ServoConfig.from_mapping({"axis_name": "x", "law_params": {"kp": 2.4, "ki": 10.0, "kd": 0.067},
                                          "ff1": 0.5}))
    a = ctrl.step(0.01, 4e-5, 1e-4, 0.0, 0.0, 0.0, 0.0)
    b = twin.step(0.01, 4e-5, 1e-4, 0.0, 0.0, 0.0, 0.0)
    assert a.feedback == b.feedback  # same gains, state kept (a fresh law would differ)
    assert a.feedforward == pytest.approx(5.0) and b.feedforward == 0.0
    assert ctrl.config.ff1 == 0.5
    fresh = servo().step(0.01, 4e-5, 1e-4, 0.0, 0.0, 0.0, 0.0)
    assert fresh.feedback != a.feedback


@pytest.mark.parametrize(("change", "message"), [
    ({"law": "p"}, "servo x: retune keeps law 'pid', got 'p' (build a new controller)"),
    ({"axis_name": "y"}, "servo x: retune keeps axis_name 'x', got 'y'"),
])
def test_retune_refuses_another_law_or_axis(change: dict, message: str) -> None:
    ctrl = servo()
    with pytest.raises(ConfigError) as info:
        ctrl.retune(ServoConfig.from_mapping({"axis_name": "x", **change}))
    assert message in str(info.value)


@pytest.mark.parametrize(("key", "value", "message"), [
    ("counts_per_m", 0, "counts_per_m must be in [0.001, 1000000000000.0], got 0"),
    ("output_limit", -1, "output_limit must be in [1e-09, 1000000000000.0], got -1"),
    ("quantum", -0.5, "quantum must be in [0.0, 1000000.0], got -0.5"),
    ("ff1", 2e6, "ff1 must be in [-1000000.0, 1000000.0], got 2000000.0"),
    ("ff1", math.nan, "ff1 must be finite, got nan"),
    ("ff2", "a lot", "ff2 must be a number, got 'a lot'"),
    ("axis_name", "", "axis_name must be a non-empty string, got ''"),
    ("law", "bang_bang", f"law must be one of {sorted(LAWS)}, got 'bang_bang'"),
    ("law_params", {"kp": -2}, "pid.kp must be in [0.0, 1000000.0], got -2"),
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
    from cnc_plant_sim.models.plant import make_plant  # the plant package is a test-only dependency

    plant = make_plant({"axes": ["x"], "variation": {"gain_pct": 0, "time_constant_pct": 0,
                                                     "friction_pct": 0}})
    ctrl = servo(law=law, law_params=law_params, quantum=quantum)
    errors = []
    for k in range(int(round(duration_s / T_S))):
        out = ctrl.step(T_S, V_R_M_S * k * T_S, V_R_M_S, 0.0, plant.positions_m()[0], plant.velocities_m_s()[0], 0.0)
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
