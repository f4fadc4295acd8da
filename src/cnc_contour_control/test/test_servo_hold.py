"""Tier 1: the servo's law is frozen while the e-stop latch blocks commands, and resumes bumplessly (no ROS)."""
from __future__ import annotations

import pytest

from cnc_contour_control.axis.safety import EstopLatch
from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.axis.servo_hold import HeldServo, HoldParams
from cnc_contour_control.core.errors import ConfigError

T_NS = 10_000_000
T_S = 0.01


def pid_state(held: HeldServo) -> tuple[float, float, float]:
    """The PID's u(k−1), e(k−1), r(k−1): its integrator and its memory."""
    law = held.controller.law
    return law._u, law._e1, law._rate1


def make(ramp_s: float = 0.2) -> tuple[HeldServo, EstopLatch]:
    latch = EstopLatch()
    controller = ServoController(ServoConfig(axis_name="x", quantum=0.0))
    return HeldServo(controller, latch, HoldParams(resume_ramp_s=ramp_s)), latch


def run(held: HeldServo, first: int, last: int, position_m: float, ref_m: float = 0.0) -> list[float]:
    """Ticks first..last with a constant reference and position: the commands."""
    return [held.step(k * T_NS, T_S, ref_m, 0.0, 0.0, position_m, 0.0, 0.0).command for k in range(first, last + 1)]


def test_the_pid_integrator_is_unchanged_across_an_estop_window() -> None:
    held, latch = make()
    run(held, 0, 9, position_m=-2e-5)  # a standing error of 2 BLU: the integrator grows
    before = pid_state(held)
    latch.estop(True, "test")
    commands = run(held, 10, 109, position_m=-5e-3)  # 1 s latched with a 500 BLU error
    assert pid_state(held) == before and before[0] != 0.0
    assert set(commands) == {0.0} and held.held_samples == 100


def test_a_plain_controller_would_have_wound_up_in_the_same_window() -> None:
    plain = ServoController(ServoConfig(axis_name="x", quantum=0.0))
    for _ in range(100):
        plain.step(T_S, 0.0, 0.0, 0.0, -5e-3, 0.0, 0.0)
    assert abs(plain.law._u) == 127.0, "the comparison: without the hold the state sits at its clamp"


def test_resume_after_reset_and_enable_starts_at_zero_error_and_closes_the_gap_smoothly() -> None:
    held, latch = make(ramp_s=0.2)
    run(held, 0, 9, position_m=0.0)
    latch.estop(True, "test")
    run(held, 10, 19, position_m=-1e-3)
    latch.estop(False, "test")
    assert latch.reset().accepted and latch.enable(True).accepted
    out = held.step(20 * T_NS, T_S, 0.0, 0.0, 0.0, -1e-3, 0.0, 0.0)
    assert out.error_m == pytest.approx(0.0, abs=1e-15) and abs(out.command) < 1.0, "no bump"
    errors = [held.step(k * T_NS, T_S, 0.0, 0.0, 0.0, -1e-3, 0.0, 0.0).error_m for k in range(21, 41)]
    steps = [b - a for a, b in zip([0.0, *errors], errors)]
    assert errors[-1] == pytest.approx(1e-3, abs=1e-15) and not held.resuming, "on the path after the ramp"
    assert max(steps) < 0.1e-3 and min(steps) >= 0.0, "the gap closes in small monotonic steps"


def test_a_disabled_axis_is_held_like_a_latched_one() -> None:
    held, latch = make()
    run(held, 0, 4, position_m=-2e-5)
    before = pid_state(held)
    latch.enable(False)
    assert set(run(held, 5, 24, position_m=-1e-3)) == {0.0} and pid_state(held) == before


def test_without_a_hold_the_servo_is_the_plain_controller_bit_for_bit() -> None:
    held, _ = make()
    plain = ServoController(ServoConfig(axis_name="x", quantum=0.0))
    for k in range(50):
        args = (T_S, 1e-4 * k, 1e-2, 0.0, 0.9e-4 * k, 0.9e-2, 0.0)
        assert held.step(k * T_NS, *args) == plain.step(*args)


def test_hold_params_refuse_a_ramp_out_of_range() -> None:
    with pytest.raises(ConfigError, match="resume_ramp_s"):
        HoldParams(resume_ramp_s=0.0)
