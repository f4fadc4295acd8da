"""Tier 2: the control nodes in-process with real rclpy and DDS (loopback), real messages."""
from __future__ import annotations

import math

import pytest
from cnc_contour_interfaces.msg import AxisCommand, Reference
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_contour_control.servo import ServoConfig, ServoController
from cnc_tools.testing import InProcessNode, TopicProbe

pytestmark = pytest.mark.nodes
SERVO_PARAMS = {"axis": "x", "sample_time_s": 0.01, "law": "pid", "law_params": "{kp: 2.4, ki: 0.1, kd: 6.7}",
                "input_timeout_s": 30.0}
PROBE = {"/cnc/servo/x/command": AxisCommand, "/diagnostics": DiagnosticArray}


def joint_state(stamp_ns: int, x_m: float) -> JointState:
    return JointState(header=_header(stamp_ns), name=["x", "y"], position=[x_m, 0.0], velocity=[0.0, 0.0])


def reference(stamp_ns: int, x_m: float, v_m_s: float = 0.0) -> Reference:
    return Reference(header=_header(stamp_ns), axis_names=["x", "y"], position_m=[x_m, 0.0],
                     velocity_m_s=[v_m_s, 0.0], acceleration_m_s2=[0.0, 0.0])


def _header(stamp_ns: int):  # noqa: ANN202
    from std_msgs.msg import Header

    return Header(stamp=ns_to_stamp(stamp_ns), frame_id="machine")


def test_servo_node_publishes_exactly_what_the_core_computes() -> None:
    core = ServoController(ServoConfig.from_mapping({"axis_name": "x", "law": "pid",
                                                     "law_params": {"kp": 2.4, "ki": 0.1, "kd": 6.7}}))
    with TopicProbe(PROBE) as probe, InProcessNode(ServoNode, SERVO_PARAMS):
        js_pub, ref_pub = probe.publisher(JointState, "/cnc/joint_states"), probe.publisher(Reference, "/cnc/reference")
        probe.wait_for(lambda: js_pub.get_subscription_count() and ref_pub.get_subscription_count(), 10.0, "servo")
        expected = []
        for k in range(10):
            stamp, x_ref, x = k * 10_000_000, 1e-5 * k * k, 0.5e-5 * k
            ref_pub.publish(reference(stamp, x_ref, 1e-3))  # reference first: matching is by stamp
            js_pub.publish(joint_state(stamp, x))
            expected.append(core.step(0.01, x_ref, 1e-3, 0.0, x).command)
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
        result = servo.node.set_parameters([Parameter("law_params", value="{kp: -1.0}")])[0]
        assert not result.successful and "kp" in result.reason and "-1" in result.reason
        result = servo.node.set_parameters([Parameter("law", value="nonsense")])[0]
        assert not result.successful and "pid" in result.reason
        result = servo.node.set_parameters([Parameter("ff1", value=0.5)])[0]
        assert result.successful and servo.node.controller.config.ff1 == 0.5
