"""Tier 1: a following-error trip a shop can reset, and the machine's state as a program sees it (no ROS).

``ferror_action: latch`` trips the servo's latch with the cause and holds the
axis (command 0); ``fault`` raises exactly what the engine raises. The
interpolator's session ends a running program as faulted when the machine
stops, holds where the machine stands and refuses goals with the cause until
the machine runs again.
"""
from __future__ import annotations

import numpy as np
import pytest

from cnc_contour_control.axis.safety import (
    EstopLatch,
    FerrorActionParams,
    FollowingErrorGuard,
    FollowingErrorLimit,
    MachineWatch,
    check_following_error,
)
from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.axis.servo_hold import HeldServo, HoldParams
from cnc_contour_control.core.errors import ConfigError, FaultError, ProgramError
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.feed_override import OverrideConfig
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.program_goal import ProgramGoal
from cnc_contour_control.motion.program_session import ProgramSession, ProgramSessionParams

T_NS = 10_000_000
T_S = 0.01
LIMIT = FollowingErrorLimit("x", min_ferror_m=1e-4, ferror_m=2e-4, ferror_velocity_m_s=0.05)


def test_a_latch_trip_latches_with_the_cause_and_allows_a_reset_once_the_axis_stands() -> None:
    latch = EstopLatch()
    guard = FollowingErrorGuard("latch", latch)
    assert guard.check(LIMIT, 1.9e-4, 0.025, 7 * T_NS) is None, "within 1e-4 + 2e-4 * 0.5 m"
    trip = guard.check(LIMIT, -2.1e-4, 0.025, 8 * T_NS)
    assert trip is not None and trip.axis_name == "x" and trip.error_m == -2.1e-4
    assert trip.bound_m == pytest.approx(2e-4) and trip.stamp_ns == 8 * T_NS
    with pytest.raises(FaultError) as raised:
        check_following_error(LIMIT, -2.1e-4, 0.025, 8 * T_NS)
    assert trip.message == str(raised.value), "the same message as the fault (and the engine)"
    assert latch.latched and latch.cause == trip.message and not latch.commands_allowed
    assert trip.values()["axis"] == "x" and float(trip.values()["ferror_bound_m"]) == pytest.approx(2e-4)
    assert not latch.enable(True).accepted and trip.message in latch.enable(True).message
    assert latch.reset().accepted and latch.enable(True).accepted and latch.commands_allowed
    assert guard.trips == 1


def test_a_fault_trip_raises_and_leaves_the_latch_alone() -> None:
    latch = EstopLatch()
    with pytest.raises(FaultError, match="servo x: following error"):
        FollowingErrorGuard("fault", latch).check(LIMIT, 5e-4, 0.0, 0)
    assert not latch.latched


@pytest.mark.parametrize("make", [lambda: FollowingErrorGuard("stop", EstopLatch()),
                                  lambda: FerrorActionParams(ferror_action="stop")])
def test_an_unknown_ferror_action_is_refused_listing_the_valid_ones(make: object) -> None:
    with pytest.raises(ConfigError, match=r"ferror_action must be one of \['fault', 'latch'\], got 'stop'"):
        make()  # type: ignore[operator]  # a parametrised callable


def held_servo(action: str) -> tuple[HeldServo, EstopLatch]:
    latch = EstopLatch()
    config = ServoConfig(axis_name="x", quantum=0.0, min_ferror_m=1e-3)
    return HeldServo(ServoController(config), latch, HoldParams(resume_ramp_s=0.1), action), latch


def test_a_latched_servo_sends_zero_from_the_tripping_tick_and_resumes_after_reset_and_enable() -> None:
    held, latch = held_servo("latch")
    ok = held.step(0, T_S, 0.0, 0.0, 0.0, -5e-4, 0.0, 0.0)
    assert ok.command != 0.0 and held.take_trip() is None
    tripped = held.step(T_NS, T_S, 0.0, 0.0, 0.0, -2e-3, 0.0, 0.0)
    assert tripped.command == 0.0 and held.held and latch.latched
    trip = held.take_trip()
    assert trip is not None and trip.stamp_ns == T_NS and trip.error_m == pytest.approx(2e-3)
    assert held.take_trip() is None, "taken once"
    later = [held.step(k * T_NS, T_S, 0.0, 0.0, 0.0, -5e-3, 0.0, 0.0) for k in range(2, 12)]
    assert {o.command for o in later} == {0.0} and held.take_trip() is None, "no trip while held"
    assert latch.reset().accepted and latch.enable(True).accepted
    resumed = held.step(12 * T_NS, T_S, 0.0, 0.0, 0.0, -5e-3, 0.0, 0.0)
    assert resumed.error_m == pytest.approx(0.0, abs=1e-15) and held.take_trip() is None, "re-based: no re-trip"


def test_a_fault_servo_raises_on_the_same_tick_the_engine_would() -> None:
    held, latch = held_servo("fault")
    held.step(0, T_S, 0.0, 0.0, 0.0, -5e-4, 0.0, 0.0)
    with pytest.raises(FaultError, match=r"at t=0\.010000 s"):
        held.step(T_NS, T_S, 0.0, 0.0, 0.0, -2e-3, 0.0, 0.0)
    assert not latch.latched


def latch_state(latched: bool, enabled: bool, cause: str = "") -> dict[str, str]:
    return {"enabled": str(enabled).lower(), "estop_latched": str(latched).lower(), "estop_cause": cause,
            "estop_input": "false", "estop_latches": "1"}


def test_the_machine_is_stopped_while_any_node_blocks_and_the_first_names_the_cause() -> None:
    watch = MachineWatch()
    watch.observe("/cnc/plant", {"ticks": "5"})  # a report without a latch: ignored
    assert not watch.stopped and watch.cause == ""
    watch.observe("/cnc/servo_x", latch_state(True, True, "servo x: following error 0.002 m"))
    watch.observe("/cnc/plant", latch_state(True, True, "/cnc/estop true at t=1.0 s"))
    assert watch.stopped and watch.cause == "/cnc/servo_x: e-stop latched (servo x: following error 0.002 m)"
    for node in ("/cnc/servo_x", "/cnc/plant"):
        watch.observe(node, latch_state(False, False))  # reset: off until enabled
    assert watch.stopped and watch.cause == "/cnc/servo_x: disabled (~/enable false)"
    watch.observe("/cnc/servo_x", latch_state(False, True))
    assert watch.blocking() == ("/cnc/plant",)
    watch.observe("/cnc/plant", latch_state(False, True))
    assert not watch.stopped and watch.cause == ""


AXES = ("x", "y")
DT_NS = 5_000_000


def session() -> ProgramSession:
    return ProgramSession(AXES, AxisLimits((0.05, 0.05), (0.5, 0.5)), InterpolatorConfig(), OverrideConfig(),
                          ProgramSessionParams(program_source="action", settle_time_s=0.0))


def test_a_stop_faults_the_running_program_holds_at_the_machine_and_refuses_goals_until_it_runs() -> None:
    s = session()
    s.step(0, [0.0, 0.0])
    s.start(*s.prepare(ProgramGoal(gcode="G1 X10 F1200\n")))
    position = np.zeros(2)
    for k in range(1, 41):
        position = s.step(k * DT_NS, position).position_m.copy()
    assert 0.0 < position[0] < 0.01
    s.machine_stopped("/cnc/servo_x: e-stop latched (servo x: following error 0.002 m)")
    outcome = s.take_outcome()
    assert outcome is not None and outcome.outcome == "faulted" and outcome.ticks == 40
    assert outcome.reason == "machine stopped: /cnc/servo_x: e-stop latched (servo x: following error 0.002 m)"
    coasting = [position + [1e-4 * k, 0.0] for k in range(1, 6)]  # the axis coasts to rest, drives off
    for k, measured in enumerate(coasting):
        sample = s.step((41 + k) * DT_NS, measured)
        assert np.array_equal(sample.position_m, measured) and not sample.velocity_m_s.any(), "at the machine"
    with pytest.raises(ProgramError, match=r"the machine is stopped: /cnc/servo_x: .*following error"):
        s.prepare(ProgramGoal(gcode="G1 X0 F1200\n"))
    s.machine_running()
    rest = coasting[-1]
    assert np.array_equal(s.step(46 * DT_NS, rest + 1e-6).position_m, rest), "holds where the machine stood"
    program, _ = s.prepare(ProgramGoal(gcode="G1 X0 F1200\n"))
    assert np.allclose(program.segments[0].start_m, rest), "the next program starts there"


def test_a_program_queued_as_the_machine_stops_ends_faulted_at_its_first_tick() -> None:
    s = session()
    s.step(0, [0.0, 0.0])
    prepared = s.prepare(ProgramGoal(gcode="G1 X10 F1200\n"))
    s.machine_stopped("/cnc/plant: e-stop latched (/cnc/estop true at t=0.0 s)")
    s.start(*prepared)
    sample = s.step(DT_NS, [1e-4, 0.0])
    outcome = s.take_outcome()
    assert outcome is not None and outcome.outcome == "faulted" and "/cnc/estop true" in outcome.reason
    assert np.array_equal(sample.position_m, [1e-4, 0.0]) and not s.busy
