"""Tier 2: the servo node with a JointTrajectory reference, frozen under the e-stop, and an input's publisher
leaving mid-tick, in-process with real rclpy."""
from __future__ import annotations

from typing import Any

import pytest
from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray
from scipy.interpolate import CubicHermiteSpline
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Header
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import AxisCommand, Reference

pytestmark = pytest.mark.nodes
T_NS = 10_000_000
PARAMS = {"axis": "x", "sample_time_s": 0.01, "law": "pid", "input_timeout_s": 30.0}
COMMANDS = "/cnc/servo/x/command"
PROBE = {COMMANDS: AxisCommand, "/diagnostics": DiagnosticArray}
TIMES_S, POSITIONS_M, VELOCITIES_M_S = [0.0, 0.04, 0.1], [0.0, 2e-4, 3e-4], [0.0, 4e-3, 0.0]


def joint_state(k: int, x_m: float) -> JointState:
    return JointState(header=Header(stamp=ns_to_stamp(k * T_NS)), name=["x", "y"], position=[x_m, 0.0],
                      velocity=[0.0, 0.0])


def trajectory() -> JointTrajectory:
    """Axes x and y, stamp 0 (from the first tick on), with velocities: cubic Hermite."""
    msg = JointTrajectory(joint_names=["y", "x"])
    for t_s, p_m, v_m_s in zip(TIMES_S, POSITIONS_M, VELOCITIES_M_S):
        msg.points.append(JointTrajectoryPoint(positions=[-1.0, p_m], velocities=[0.0, v_m_s],
                                               time_from_start=Duration(sec=0, nanosec=round(t_s * 1e9))))
    return msg


def call(probe: TopicProbe, srv_type: type, name: str, request: Any) -> Any:
    return probe.call(srv_type, name, request)


def test_a_joint_trajectory_is_sampled_at_each_ticks_stamp_and_held_after_its_end() -> None:
    spline = CubicHermiteSpline(TIMES_S, POSITIONS_M, VELOCITIES_M_S)
    core = ServoController(ServoConfig(axis_name="x"))
    params = {**PARAMS, "reference_source": "joint_trajectory", "trajectory_topic": "planner/trajectory"}
    with TopicProbe(PROBE) as probe, InProcessNode(ServoNode, params) as servo:
        js_pub = probe.publisher(JointState, "/cnc/joint_states")
        trajectory_pub = probe.node.create_publisher(JointTrajectory, "/cnc/planner/trajectory", 10)
        probe.wait_for(lambda: trajectory_pub.get_subscription_count() > 0, 10.0, "the trajectory reader")
        trajectory_pub.publish(trajectory())
        probe.wait_for(lambda: servo.node.trajectory.received == 1, 10.0, "the trajectory")
        expected = []
        for k in range(15):
            x_m, t_s = 0.8e-5 * k, min(k * 0.01, TIMES_S[-1])
            ref = (float(spline(t_s)), float(spline(t_s, 1)), float(spline(t_s, 2))) if k * 0.01 < TIMES_S[-1] \
                else (POSITIONS_M[-1], 0.0, 0.0)
            expected.append(core.step(0.01, *ref, x_m, 0.0, 0.0).command)
            js_pub.publish(joint_state(k, x_m))
        probe.wait_for(lambda: len(probe.received(COMMANDS)) == 15, 10.0, "15 commands")
    commands = [m.command for m in probe.received(COMMANDS)]
    assert commands == pytest.approx(expected, abs=1.0), "to one DAC step (the quantum: ulp differences round)"
    assert sum(a == b for a, b in zip(commands, expected)) >= 13 and max(map(abs, commands)) > 5.0


def test_the_estop_freezes_the_law_and_reset_and_enable_resume_without_a_bump() -> None:
    with TopicProbe(PROBE) as probe, InProcessNode(ServoNode, PARAMS) as servo:
        js_pub, ref_pub = probe.publisher(JointState, "/cnc/joint_states"), probe.publisher(Reference, "/cnc/reference")
        estop = probe.node.create_publisher(Bool, "/cnc/estop", 10)
        probe.wait_for(lambda: js_pub.get_subscription_count() and estop.get_subscription_count(), 10.0, "servo")

        def ticks(first: int, last: int, x_m: float) -> list[float]:
            for k in range(first, last + 1):
                ref_pub.publish(Reference(header=Header(stamp=ns_to_stamp(k * T_NS)), axis_names=["x"],
                                          position_m=[1e-4], velocity_m_s=[0.0], acceleration_m_s2=[0.0]))
                js_pub.publish(joint_state(k, x_m))
            probe.wait_for(lambda: len(probe.received(COMMANDS)) == last + 1, 10.0, f"tick {last}")
            return [m.command for m in probe.received(COMMANDS)[first:]]

        driving = ticks(0, 9, 0.0)
        law = servo.node.controller.law
        state = (law._u, law._e1, law._rate1)
        estop.publish(Bool(data=True))
        probe.wait_for(lambda: servo.node.latch.latched, 10.0, "the latch")
        latched = ticks(10, 59, -2e-3)
        frozen = (law._u, law._e1, law._rate1)
        estop.publish(Bool(data=False))
        probe.wait_for(lambda: not servo.node.latch.estop_input, 10.0, "the input released")
        assert call(probe, Trigger, "/cnc/servo/reset", Trigger.Request()).success
        assert call(probe, SetBool, "/cnc/servo/enable", SetBool.Request(data=True)).success
        resumed = ticks(60, 61, -2e-3)
    assert driving[-1] > 0.0 and set(latched) == {0.0}
    assert frozen == state, "the law did not integrate the 2 mm error of the latched half second"
    assert abs(resumed[0]) <= 1.0 < abs(resumed[1]), "resumes from zero error, then acts"


def test_an_input_whose_publisher_leaves_while_a_tick_waits_is_a_fault_naming_it() -> None:
    with TopicProbe(PROBE, name="interpolator", namespace="/cnc") as probe, InProcessNode(ServoNode, PARAMS) as servo:
        js_pub, ref_pub = probe.publisher(JointState, "/cnc/joint_states"), probe.publisher(Reference, "/cnc/reference")
        probe.wait_for(lambda: js_pub.get_subscription_count() and ref_pub.get_subscription_count(), 10.0, "servo")
        ref_pub.publish(Reference(header=Header(stamp=ns_to_stamp(0)), axis_names=["x"], position_m=[0.0],
                                  velocity_m_s=[0.0], acceleration_m_s2=[0.0]))
        js_pub.publish(joint_state(0, 0.0))
        probe.wait_for(lambda: servo.node.partners.watch.publishers("/cnc/reference") == ("/cnc/interpolator",),
                       10.0, "the servo to know the reference's publisher")
        js_pub.publish(joint_state(1, 0.0))  # tick 1 waits for its reference ...
        probe.wait_for(lambda: servo.node.matcher.pending_count == 1, 10.0, "tick 1 pending")
        probe.node.destroy_publisher(ref_pub)  # ... whose publisher leaves
        probe.wait_for(lambda: servo.node.finished, 5.0, "the fault")  # << input_timeout_s 30 s
    assert servo.node.fault_message == ("servo x: /cnc/interpolator left the graph: /cnc/reference has 0 publishers "
                                        "(had 1) at t=0.000000 s")
