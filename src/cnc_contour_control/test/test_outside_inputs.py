"""Bad messages on outside topics (a planner's trajectory, an operator's feed override) are refused and counted on
``/diagnostics``; the machine goes on. Tier 1 for the rules, tier 2 (real rclpy) for the nodes."""
from __future__ import annotations

import math
from typing import Any

import pytest
from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.motion.feed_override import OverrideInbox, message_ratio
from cnc_contour_control.motion.trajectory_reference import TrajectoryFollower
from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import AxisCommand, FeedOverride, Reference

T_NS = 10_000_000


# ----------------------------------------------------------------------------------------------- tier 1
@pytest.mark.parametrize("requested, applied, quantum, ratio", [
    (0.5, 0.0, 0.0, 0.5),     # a bare request (an operator's): taken
    (0.47, 0.0, 0.1, 0.5),    # a bare request on the quantum's levels
    (1.3, 0.7, 0.1, 0.7),     # a switch's applied ratio: taken
    (-0.4, 0.0, 0.1, 0.0),    # a switch clipped the request to its hold
    (0.03, 0.0, 0.1, 0.0),    # a switch rounded it to the hold
    (0.0, 0.0, 0.0, 0.0),     # a hold
    (-0.4, 0.0, 0.0, -0.4),   # a bare negative request: refused by the inbox
])
def test_the_ratio_of_a_feed_override_message(requested: float, applied: float, quantum: float, ratio: float) -> None:
    assert message_ratio(requested, applied, quantum) == pytest.approx(ratio)


@pytest.mark.parametrize("ratio", [-0.4, 1.6, math.nan, math.inf])
def test_a_ratio_out_of_range_is_refused_naming_the_bound_and_the_last_valid_is_held(ratio: float) -> None:
    inbox = OverrideInbox(previous_tick=False, max_ratio=1.5)
    assert inbox.add(0, 0.8) is None
    reason = inbox.add(T_NS, ratio)
    assert reason is not None and "max_ratio = 1.5" in reason and str(ratio) in reason and inbox.latest == 0.8


def test_a_stale_or_future_trajectory_is_refused_and_the_current_kept() -> None:
    follower = TrajectoryFollower("x", horizon_ns=10 * T_NS)
    follower.take(0, [0.0, 0.1], [0.0, 1e-3])
    follower.sample(100 * T_NS, 0.0)
    with pytest.raises(FaultError, match=r"stale trajectory: stamped 0.500000 s, it ends at 0.600000 s, before "
                                         r"the current tick at 1.000000 s"):
        follower.take(50 * T_NS, [0.0, 0.1], [0.0, 2e-3])
    with pytest.raises(FaultError, match=r"trajectory from the future: stamped 2.000000 s, more than 0.1 s after"):
        follower.take(200 * T_NS, [0.0, 0.1], [0.0, 2e-3])
    with pytest.raises(FaultError, match=r"positions\[1\] must be finite, got nan"):
        follower.take(0, [0.0, 0.1], [0.0, math.nan])
    assert follower.received == 1 and follower.sample(120 * T_NS, 0.0)[0] == pytest.approx(1e-3)
    follower.take(115 * T_NS, [0.0, 0.1], [0.0, 2e-3])  # started in the past, still running: taken
    assert follower.received == 2


# ----------------------------------------------------------------------------------------------- tier 2
def refusals(probe: TopicProbe, topic: str) -> list[Any]:
    return [s for a in probe.received("/diagnostics") for s in a.status
            if any(kv.key == "topic" and kv.value == topic for kv in s.values)]


def values(status: Any) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def joint_state(k: int) -> JointState:
    return JointState(header=Header(stamp=ns_to_stamp(k * T_NS)), name=["x", "y"], position=[0.0, 0.0],
                      velocity=[0.0, 0.0])


def trajectory(names: list[str], positions: list[list[float]]) -> JointTrajectory:
    msg = JointTrajectory(joint_names=names)
    for i, point in enumerate(positions):
        msg.points.append(JointTrajectoryPoint(positions=point,
                                               time_from_start=Duration(sec=0, nanosec=i * 50_000_000)))
    return msg


@pytest.mark.nodes
def test_a_trajectory_without_the_servos_axis_or_with_nan_is_refused_counted_and_the_servo_goes_on() -> None:
    params = {"axis": "x", "sample_time_s": 0.01, "law": "pid", "input_timeout_s": 30.0,
              "reference_source": "joint_trajectory", "trajectory_topic": "planner/trajectory"}
    commands = "/cnc/servo/x/command"
    with TopicProbe({commands: AxisCommand, "/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(ServoNode, params) as servo:
        js_pub = probe.publisher(JointState, "/cnc/joint_states")
        pub = probe.node.create_publisher(JointTrajectory, "/cnc/planner/trajectory", 10)
        probe.wait_for(lambda: pub.get_subscription_count() > 0 and js_pub.get_subscription_count() > 0, 10.0,
                       "the servo's readers")
        pub.publish(trajectory(["y"], [[0.0], [1e-3]]))
        pub.publish(trajectory(["x", "y"], [[0.0, 0.0], [math.nan, 0.0]]))
        pub.publish(trajectory(["x", "y"], [[0.0, 0.0], [2e-4, 0.0]]))
        probe.wait_for(lambda: servo.node.trajectory.received == 1, 10.0, "the good trajectory")
        probe.wait_for(lambda: refusals(probe, "/cnc/planner/trajectory"), 10.0, "the refusal on /diagnostics")
        for k in range(8):
            js_pub.publish(joint_state(k))
        probe.wait_for(lambda: len(probe.received(commands)) == 8, 10.0, "8 commands")
        assert not servo.node.finished and servo.node.fault_message is None
    first = refusals(probe, "/cnc/planner/trajectory")[0]
    assert first.level == DiagnosticStatus.WARN and values(first)["refused_count"] == "1"
    assert "has no joint 'x'" in first.message and "['y']" in first.message
    assert max(abs(m.command) for m in probe.received(commands)) > 0.0, "the good trajectory drives the axis"


@pytest.mark.nodes
def test_a_bare_feed_override_request_is_applied_and_an_out_of_range_one_refused_and_counted() -> None:
    params = {"axes": ["x", "y"], "program_file": "", "program_source": "action", "feed_override_source": "topic",
              "feed_override.max_ratio": 1.5}
    with TopicProbe({"/cnc/reference": Reference, "/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(InterpolatorNode, params) as interpolator:
        override = probe.publisher(FeedOverride, "/cnc/feed_override", 10)
        probe.wait_for(lambda: override.get_subscription_count() > 0, 10.0, "the override's reader")
        override.publish(FeedOverride(requested_ratio=0.5))
        probe.wait_for(lambda: interpolator.node.inbox.latest == 0.5, 10.0, "the bare request applied")
        override.publish(FeedOverride(requested_ratio=1.9, applied_ratio=1.9))
        override.publish(FeedOverride(requested_ratio=-1.0))
        probe.wait_for(lambda: interpolator.node.override_refusals.count == 2, 10.0, "two refusals")
        probe.wait_for(lambda: refusals(probe, "/cnc/feed_override"), 10.0, "the refusal on /diagnostics")
        assert interpolator.node.inbox.latest == 0.5 and not interpolator.node.finished
    first = refusals(probe, "/cnc/feed_override")[0]
    assert first.level == DiagnosticStatus.WARN and "max_ratio = 1.5" in first.message and "1.9" in first.message
