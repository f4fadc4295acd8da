"""Tier 2: tolerances on RunProgram goals and FollowTrajectory goals, in-process with real rclpy.

An action-mode interpolator on three axes is ticked by the test: each joint
state is the previous reference plus an offset the test chooses (a machine that
lags where the test says). Every goal ends with its code and a reason naming the
axis (or the contour), the amount, the time and the G-code line; a trajectory
naming x and y moves them and holds z; ``~/controller_state`` carries
reference, feedback and error per axis, and says that it does not know the output.
"""
from __future__ import annotations

import math
import uuid
from collections.abc import Callable
from typing import Any

import pytest
from builtin_interfaces.msg import Duration
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from cnc_contour_control.nodes.common import ns_to_stamp, stamp_to_ns
from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.testing import InProcessNode, ThreadSafeActionClient, TopicProbe
from cnc_contour_interfaces.action import FollowTrajectory, RunProgram
from cnc_contour_interfaces.msg import ControllerState, JointTolerance, Reference

pytestmark = pytest.mark.nodes
T_NS = 10_000_000
AXES = ["x", "y", "z"]
PARAMS = {"axes": AXES, "program_source": "action", "program_file": "", "settle_time_s": 0.0,
          "feedback_period_s": 0.05, "goal_time_s": 0.3, "controller_state_decimation": 5}
Offset = Callable[[list[float]], list[float]]


def no_offset(reference: list[float]) -> list[float]:
    return [0.0, 0.0, 0.0]


class Machine:
    """The test's lockstep: joint state k (the last reference plus ``offset``), then wait for reference k."""

    def __init__(self, probe: TopicProbe, ns: str) -> None:
        self.probe, self.ns, self.k = probe, ns, 0
        self.pub = probe.publisher(JointState, f"{ns}/joint_states")
        self.reference_m = [0.0, 0.0, 0.0]
        self.offset: Offset = no_offset
        self.references: list[list[float]] = []

    def tick(self) -> None:
        position = [r + o for r, o in zip(self.reference_m, self.offset(self.reference_m))]
        self.pub.publish(JointState(header=Header(stamp=ns_to_stamp(self.k * T_NS)), name=AXES,
                                    position=position, velocity=[0.0, 0.0, 0.0]))
        stamp = self.k * T_NS

        def refs() -> list[Any]:
            return [m for m in self.probe.received(f"{self.ns}/reference") if stamp_to_ns(m.header.stamp) == stamp]

        self.probe.wait_for(lambda: bool(refs()), 20.0, f"reference {self.k}")
        self.reference_m = list(refs()[0].position_m)
        self.references.append(self.reference_m)
        self.k += 1

    def until(self, future: Any, max_ticks: int = 3000) -> Any:
        for _ in range(max_ticks):
            if future.done():
                return future.result()
            self.tick()
        raise AssertionError(f"no answer within {max_ticks} ticks")

    def run(self, client: ThreadSafeActionClient, goal: Any, offset: Offset = no_offset,
            cancel_after: int | None = None) -> Any:
        self.offset = no_offset
        handle = self.until(client.send_goal_async(goal))
        assert handle.accepted, "every goal is accepted; a refusal is its result"
        self.offset = offset
        result = handle.get_result_async()
        for i in range(3000):
            if result.done():
                break
            if i == cancel_after:
                self.until(handle.cancel_goal_async())
            self.tick()
        self.offset = no_offset
        return self.until(result).result


def lag_y(reference: list[float]) -> list[float]:
    """y lags 0.3 mm while it is between 0 and 5 mm (line 2 of PROGRAM)."""
    return [0.0, -3e-4 if 1e-9 < reference[1] < 0.005 - 1e-9 else 0.0, 0.0]


def stuck_x(reference: list[float]) -> list[float]:
    """x stands 0.2 mm short once its reference passed 4.9 mm."""
    return [-2e-4 if reference[0] > 0.0049 else 0.0, 0.0, 0.0]


PROGRAM = "G1 X5 F1200\nG1 Y5\n"


def tolerance(name: str, position_m: float, velocity_m_s: float = 0.0) -> JointTolerance:
    return JointTolerance(name=name, position=position_m, velocity=velocity_m_s)


def back_home(machine: Machine, client: ThreadSafeActionClient) -> None:
    result = machine.run(client, RunProgram.Goal(gcode="G0 X0 Y0 Z0"))
    assert result.outcome == RunProgram.Result.COMPLETED, (result.reason, machine.reference_m)


def test_run_program_goals_end_with_their_tolerance_codes_naming_axis_amount_time_and_line() -> None:
    ns = f"/tol_{uuid.uuid4().hex[:8]}"
    with TopicProbe({f"{ns}/reference": Reference}) as probe, InProcessNode(InterpolatorNode, PARAMS, namespace=ns):
        client = ThreadSafeActionClient(probe.node, RunProgram, f"{ns}/run_program")
        probe.wait_for(client.server_is_ready, 20.0, "the RunProgram server")
        machine = Machine(probe, ns)
        probe.wait_for(lambda: machine.pub.get_subscription_count() > 0, 20.0, "the joint_states reader")
        machine.tick()  # the position known: a goal before any joint state is refused
        complete = machine.run(client, RunProgram.Goal(gcode=PROGRAM))
        back_home(machine, client)
        path = machine.run(client, RunProgram.Goal(gcode=PROGRAM, path_tolerance=[tolerance("y", 2e-4)]), lag_y)
        back_home(machine, client)
        contour = machine.run(client, RunProgram.Goal(gcode=PROGRAM, contour_tolerance_mm=0.1), lag_y)
        back_home(machine, client)
        unchecked = machine.run(client, RunProgram.Goal(gcode=PROGRAM, path_tolerance=[tolerance("y", -1.0)]),
                                lag_y)
        back_home(machine, client)
        goal = machine.run(client, RunProgram.Goal(gcode=PROGRAM, goal_tolerance=[tolerance("x", 1e-4)],
                                                   goal_time_s=0.1), stuck_x)
        back_home(machine, client)
        goal_time = machine.run(client, RunProgram.Goal(gcode=PROGRAM), stuck_x)
        unknown = machine.run(client, RunProgram.Goal(gcode=PROGRAM, path_tolerance=[tolerance("w", 1e-3)]))
        cancel = machine.run(client, RunProgram.Goal(gcode="G1 X20 F1200"), cancel_after=10)

    assert complete.outcome == RunProgram.Result.COMPLETED and "within its goal tolerance" in complete.reason
    assert path.outcome == RunProgram.Result.PATH_TOLERANCE_VIOLATED == 6, path.reason
    for word in ("axis y 0.", "mm from its reference (tolerance 0.2 mm) at ", " s, G-code line 2"):
        assert word in path.reason, (word, path.reason)
    assert contour.outcome == RunProgram.Result.PATH_TOLERANCE_VIOLATED, contour.reason
    for word in ("contour 0.", "(tolerance 0.1 mm)", "G-code line 2"):
        assert word in contour.reason, (word, contour.reason)
    assert unchecked.outcome == RunProgram.Result.COMPLETED, "a negative tolerance is not checked"
    assert goal.outcome == RunProgram.Result.GOAL_TOLERANCE_VIOLATED == 7, goal.reason
    for word in ("axis x 0.2000 mm from its end (tolerance 0.1 mm)", "(goal_time_s 0.1)", "G-code line 2"):
        assert word in goal.reason, (word, goal.reason)
    assert goal_time.outcome == RunProgram.Result.GOAL_TOLERANCE_VIOLATED, goal_time.reason
    assert "(tolerance 0.01 mm)" in goal_time.reason and "(goal_time_s 0.3)" in goal_time.reason
    assert unknown.outcome == RunProgram.Result.REJECTED and "unknown axis 'w'" in unknown.reason
    assert cancel.outcome == RunProgram.Result.CANCELED, cancel.reason


def point(seconds: float, positions: list[float]) -> JointTrajectoryPoint:
    return JointTrajectoryPoint(positions=positions, time_from_start=Duration(sec=int(seconds),
                                                                              nanosec=round(seconds % 1 * 1e9)))


def test_a_trajectory_of_two_of_three_axes_moves_them_holds_the_third_and_the_state_is_published() -> None:
    ns = f"/traj_{uuid.uuid4().hex[:8]}"
    state_topic = f"{ns}/interpolator/controller_state"
    with TopicProbe({f"{ns}/reference": Reference, state_topic: ControllerState}) as probe, \
            InProcessNode(InterpolatorNode, PARAMS, namespace=ns):
        client = ThreadSafeActionClient(probe.node, FollowTrajectory, f"{ns}/follow_trajectory")
        probe.wait_for(client.server_is_ready, 20.0, "the FollowTrajectory server")
        machine = Machine(probe, ns)
        probe.wait_for(lambda: machine.pub.get_subscription_count() > 0, 20.0, "the joint_states reader")
        machine.tick()
        start = machine.k
        trajectory = JointTrajectory(joint_names=["y", "x"],
                                     points=[point(0.5, [0.004, 0.002]), point(1.0, [0.006, 0.004])])
        done = machine.run(client, FollowTrajectory.Goal(trajectory=trajectory))
        refs = machine.references[start:]
        bad_joint = machine.run(client, FollowTrajectory.Goal(trajectory=JointTrajectory(
            joint_names=["q"], points=[point(1.0, [0.0])])))
        old = machine.run(client, FollowTrajectory.Goal(trajectory=JointTrajectory(
            header=Header(stamp=ns_to_stamp(T_NS)), joint_names=["x"], points=[point(0.1, [0.0])])))
        stuck = machine.run(client, FollowTrajectory.Goal(
            trajectory=JointTrajectory(joint_names=["x"], points=[point(0.5, [0.0])]),
            goal_tolerance=[tolerance("x", 1e-4)], goal_time_tolerance=Duration(nanosec=100_000_000)),
            lambda ref: [2e-4, 0.0, 0.0])
        cancelled = machine.run(client, FollowTrajectory.Goal(trajectory=JointTrajectory(
            joint_names=["x", "y"], points=[point(2.0, [0.02, 0.01])])), cancel_after=60)
        states = probe.received(state_topic)

    assert done.error_code == FollowTrajectory.Result.SUCCESSFUL, done.error_string
    assert all(r[2] == 0.0 for r in refs), "z, not named, held"
    assert refs[-1][0] == pytest.approx(0.004) and refs[-1][1] == pytest.approx(0.006)
    # time_from_start counts from the goal's first tick, whichever tick the goal reached the node on: y is at its
    # first point (0.004 at 0.5 s) exactly 50 ticks after it left the hold
    at_point = next(i for i, r in enumerate(refs) if abs(r[1] - 0.004) <= 1e-9)
    assert refs[at_point - 50][1] == 0.0 and refs[at_point - 49][1] != 0.0, "time_from_start from the goal's first tick"
    assert bad_joint.error_code == FollowTrajectory.Result.INVALID_JOINTS and "'q'" in bad_joint.error_string
    assert old.error_code == FollowTrajectory.Result.OLD_HEADER_TIMESTAMP, old.error_string
    assert "before the latest tick" in old.error_string
    assert stuck.error_code == FollowTrajectory.Result.GOAL_TOLERANCE_VIOLATED == -5, stuck.error_string
    assert "axis x 0.2000 mm from its end (tolerance 0.1 mm)" in stuck.error_string
    assert cancelled.error_code == FollowTrajectory.Result.CANCELED, cancelled.error_string
    stamps = [stamp_to_ns(s.header.stamp) for s in states]
    assert stamps and all(b - a == 5 * T_NS for a, b in zip(stamps, stamps[1:])), "every 5 ticks"
    state = states[-1]
    assert list(state.joint_names) == AXES and not state.output_known and all(map(math.isnan, state.output))
    assert "servo/<axis>/command" in state.output_source
    assert [r - f for r, f in zip(state.reference_position_m, state.feedback_position_m)] == pytest.approx(
        list(state.error_position_m))
