"""Tier 2: the control nodes in-process with real rclpy and DDS (loopback), real messages."""
from __future__ import annotations

import math

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import AxisCommand, Reference

pytestmark = pytest.mark.nodes
SERVO_PARAMS = {"axis": "x", "sample_time_s": 0.01, "law": "pid", "gains.kp": 2.4, "gains.ki": 10.0, "gains.kd": 0.067,
                "input_timeout_s": 30.0}
PROBE = {"/cnc/servo/x/command": AxisCommand, "/diagnostics": DiagnosticArray}


def joint_state(stamp_ns: int, x_m: float) -> JointState:
    return JointState(header=_header(stamp_ns), name=["x", "y"], position=[x_m, 0.0], velocity=[0.0, 0.0])


def reference(stamp_ns: int, x_m: float, v_m_s: float = 0.0) -> Reference:
    return Reference(header=_header(stamp_ns), axis_names=["x", "y"], position_m=[x_m, 0.0],
                     velocity_m_s=[v_m_s, 0.0], acceleration_m_s2=[0.0, 0.0])


def _header(stamp_ns: int):
    from std_msgs.msg import Header

    return Header(stamp=ns_to_stamp(stamp_ns), frame_id="machine")


def test_servo_node_publishes_exactly_what_the_core_computes() -> None:
    core = ServoController(ServoConfig.from_mapping({"axis_name": "x", "law": "pid",
                                                     "law_params": {"kp": 2.4, "ki": 10.0, "kd": 0.067}}))
    with TopicProbe(PROBE) as probe, InProcessNode(ServoNode, SERVO_PARAMS):
        js_pub, ref_pub = probe.publisher(JointState, "/cnc/joint_states"), probe.publisher(Reference, "/cnc/reference")
        probe.wait_for(lambda: js_pub.get_subscription_count() and ref_pub.get_subscription_count(), 10.0, "servo")
        expected = []
        for k in range(10):
            stamp, x_ref, x = k * 10_000_000, 1e-5 * k * k, 0.5e-5 * k
            ref_pub.publish(reference(stamp, x_ref, 1e-3))  # reference first: matching is by stamp
            js_pub.publish(joint_state(stamp, x))
            expected.append(core.step(0.01, x_ref, 1e-3, 0.0, x, 0.0, 0.0).command)
        probe.wait_for(lambda: len(probe.received("/cnc/servo/x/command")) == 10, 10.0, "10 commands")
    commands = probe.received("/cnc/servo/x/command")
    assert [m.command for m in commands] == expected
    assert [m.header.stamp.nanosec for m in commands] == [k * 10_000_000 for k in range(10)]
    assert all(m.law == "pid" and m.command_unit == "dac" for m in commands)


def test_servo_node_refuses_a_non_finite_reference_and_reports_it() -> None:
    with TopicProbe(PROBE) as probe, InProcessNode(ServoNode, SERVO_PARAMS) as servo:
        js_pub, ref_pub = probe.publisher(JointState, "/cnc/joint_states"), probe.publisher(Reference, "/cnc/reference")
        probe.wait_for(lambda: js_pub.get_subscription_count() and ref_pub.get_subscription_count(), 10.0, "servo")
        ref_pub.publish(reference(0, math.nan))
        js_pub.publish(joint_state(0, 0.0))
        probe.wait_for(lambda: probe.received("/diagnostics"), 10.0, "a diagnostic")
        assert servo.node.finished
    status = probe.received("/diagnostics")[0].status[0]
    assert status.level == DiagnosticStatus.ERROR
    assert "non-finite" in status.message and "reference[x]" in status.message
    assert probe.received("/cnc/servo/x/command") == [], "no command computed from bad data"


def test_servo_node_refuses_bad_parameters_with_the_reason() -> None:
    with InProcessNode(ServoNode, SERVO_PARAMS) as servo:
        result = servo.node.set_parameters([Parameter("gains.kp", value=-1.0)])[0]
        assert not result.successful and "gains.kp" in result.reason and "-1" in result.reason
        result = servo.node.set_parameters([Parameter("law", value="nonsense")])[0]
        assert not result.successful and "read-only" in result.reason
        result = servo.node.set_parameters([Parameter("ff1", value=0.5)])[0]
        assert result.successful and servo.node.controller.config.ff1 == 0.5


def _far_future(pubs: dict) -> None:
    pubs["reference"].publish(reference(0, 0.0))
    pubs["joint_states"].publish(joint_state(0, 0.0))
    pubs["joint_states"].publish(joint_state(1000 * 1_000_000_000, 0.0))  # well formed, not of this run


def _stale_nan(pubs: dict) -> None:
    for k in range(2):
        pubs["reference"].publish(reference(k * 10_000_000, 0.0))
        pubs["joint_states"].publish(joint_state(k * 10_000_000, 0.0))
    pubs["reference"].publish(reference(0, math.nan))  # stamped at a tick already answered


def _empty_reference(pubs: dict) -> None:
    pubs["reference"].publish(Reference(header=_header(0), axis_names=["x", "y"]))


def _joint_state_without_the_axis(pubs: dict) -> None:
    pubs["joint_states"].publish(JointState(header=_header(0), name=["y"], position=[0.0], velocity=[0.0]))


@pytest.mark.parametrize(("send", "words"), [
    (_far_future, ["/cnc/joint_states", "t=1000.000000 s", "outside the run"]),
    (_stale_nan, ["/cnc/reference", "non-finite", "reference[x]"]),
    (_empty_reference, ["/cnc/reference", "reference.position_m has 0 values for 2 axis_names"]),
    (_joint_state_without_the_axis, ["/cnc/joint_states", "no axis 'x'"]),
], ids=["far-future stamp", "stale NaN", "empty Reference arrays", "JointState without the axis"])
def test_servo_node_faults_on_a_message_from_outside_the_run_naming_the_topic(send, words: list[str]) -> None:
    with TopicProbe(PROBE) as probe, InProcessNode(ServoNode, SERVO_PARAMS) as servo:
        pubs = {"joint_states": probe.publisher(JointState, "/cnc/joint_states"),
                "reference": probe.publisher(Reference, "/cnc/reference")}
        probe.wait_for(lambda: all(p.get_subscription_count() for p in pubs.values())
                       and servo.node.status_publisher.get_subscription_count(), 20.0, "servo and its statuses matched")
        send(pubs)
        probe.wait_for(lambda: servo.node.finished and probe.received("/diagnostics"), 10.0, "a fault")
    status = probe.received("/diagnostics")[-1].status[0]
    assert status.level == DiagnosticStatus.ERROR
    assert all(word in status.message for word in words), status.message
    assert {kv.key: kv.value for kv in status.values}["run_id"] == "/cnc", "the status says whose run it is"
