"""Tier 2: homing and travel limits on the interpolator in action mode, in-process with real rclpy.

The test ticks a perfect machine (each joint state the previous reference,
``test_program_goals_node.Machine``). With ``require_homing`` a goal ends
REJECTED "axis x is not homed; call home first"; the ``home`` service moves
the axes, one at a time, to the home position through the reference and the
homed state turns true on ``/diagnostics``; a goal leaving the travel ends
REJECTED naming line, axis and excess before any axis moved; one inside runs.
A servo's JointTrajectory past its ``travel_mm`` is refused and counted, never an exit.
"""
from __future__ import annotations

import uuid

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_contour_control.testing import InProcessNode, ThreadSafeActionClient, TopicProbe, sibling_module
from cnc_contour_interfaces.action import RunProgram
from cnc_contour_interfaces.msg import AxisCommand, Reference

pytestmark = pytest.mark.nodes
_GOALS = sibling_module(__file__, "test_program_goals_node")
_INPUTS = sibling_module(__file__, "test_outside_inputs")
PARAMS = {"axes": ["x", "y"], "program_source": "action", "program_file": "", "settle_time_s": 0.02,
          "feedback_period_s": 0.05, "require_homing": True, "home_position_mm": [2.0, 1.0],
          "homing_feed_mm_min": [1200.0, 600.0], "travel_axes": ["x", "y"], "travel_min_mm": [-1.0, -1.0],
          "travel_max_mm": [10.0, 10.0]}


def homed_states(probe: TopicProbe, ns: str) -> list[tuple[int, dict[str, str]]]:
    """(level, values) of every interpolator status carrying the homed state."""
    out = []
    for array in probe.received("/diagnostics"):
        for status in array.status:
            values = {kv.key: kv.value for kv in status.values}
            if status.name == f"{ns}/interpolator" and "homed.x" in values:
                out.append((int.from_bytes(status.level, "little"), values))
    return out


def test_require_homing_then_home_then_travel_limits_refuse_before_any_move() -> None:
    ns = f"/homing_{uuid.uuid4().hex[:8]}"
    with TopicProbe({f"{ns}/reference": Reference, "/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(InterpolatorNode, PARAMS, namespace=ns):
        client = ThreadSafeActionClient(probe.node, RunProgram, f"{ns}/run_program")
        probe.wait_for(client.server_is_ready, 20.0, "the RunProgram server")
        machine = _GOALS.Machine(probe, ns)
        probe.wait_for(lambda: machine.pub.get_subscription_count() > 0, 20.0, "the joint_states reader")
        machine.position_m = [0.004, 0.003]
        machine.tick()  # the position known before the first goal (else that goal is refused for it)
        unhomed = _GOALS.run_goal(machine, client, RunProgram.Goal(gcode="G1 X5 F1200"))
        assert unhomed.outcome == RunProgram.Result.REJECTED
        assert unhomed.reason == "axis x is not homed; call home first"
        probe.wait_for(lambda: any(v["homed.x"] == "false" for _, v in homed_states(probe, ns)), 10.0,
                       "the homed state on /diagnostics")
        assert homed_states(probe, ns)[-1][0] == int.from_bytes(DiagnosticStatus.WARN, "little")
        answer = probe.call(Trigger, f"{ns}/interpolator/home", Trigger.Request())
        assert answer.success and "homing started: 2 moves" in answer.message, answer.message
        busy = probe.call(Trigger, f"{ns}/interpolator/home", Trigger.Request())
        assert not busy.success and "busy" in busy.message
        path = []
        for _ in range(3000):
            machine.tick()
            path.append(list(machine.position_m))
            if homed_states(probe, ns) and homed_states(probe, ns)[-1][1]["homed.y"] == "true":
                break
        level, values = homed_states(probe, ns)[-1]
        assert values["homed.x"] == values["homed.y"] == values["require_homing"] == "true"
        assert level == int.from_bytes(DiagnosticStatus.OK, "little")
        assert machine.position_m == pytest.approx([0.002, 0.001], abs=1e-9)
        x_done = next(i for i, p in enumerate(path) if abs(p[0] - 0.002) < 1e-9)
        assert all(abs(p[1] - 0.003) < 1e-12 for p in path[:x_done])  # x first, y held meanwhile
        before = list(machine.position_m)
        outside = _GOALS.run_goal(machine, client, RunProgram.Goal(gcode="G1 X5 F1200\nG1 X12\n"))
        assert outside.outcome == RunProgram.Result.REJECTED
        assert "line 2 takes axis x to 12.000000 mm, 2.000000 mm beyond its travel_max_mm 10" in outside.reason
        assert machine.position_m == before and outside.ticks == 0
        inside = _GOALS.run_goal(machine, client, RunProgram.Goal(gcode="G1 X5 F1200\nG2 X9 Y1 R2\n"))
        assert inside.outcome == RunProgram.Result.COMPLETED, inside.reason
        touching = _GOALS.run_goal(machine, client, RunProgram.Goal(gcode="G3 X5 Y1 I-2 J0 F1200\nG3 X9 Y1 I2 J0\n"))
        assert touching.outcome == RunProgram.Result.COMPLETED, touching.reason  # its lowest point is y -1 exactly
        deep = _GOALS.run_goal(machine, client, RunProgram.Goal(gcode="G91 G2 X-6 Y0 I-3 J0 F1200\n"))
        assert deep.outcome == RunProgram.Result.REJECTED  # the half circle dips to y -2: ends inside, arc not
        assert "line 1 takes axis y to -2.000000 mm, 1.000000 mm beyond its travel_min_mm -1" in deep.reason



def test_a_joint_trajectory_leaving_the_servos_travel_is_refused_counted_and_the_servo_goes_on() -> None:
    """A servo with ``travel_mm``: a trajectory past it (by 1 mm at its second point) is refused and counted on
    /diagnostics naming the point, the axis and the excess; the one inside drives the axis; nothing exits."""
    inputs = _INPUTS
    ns = f"/travel_{uuid.uuid4().hex[:8]}"
    params = {"axis": "x", "sample_time_s": 0.01, "law": "pid", "input_timeout_s": 30.0, "travel_mm": [-1.0, 1.0],
              "reference_source": "joint_trajectory", "trajectory_topic": "planner/trajectory"}
    topic, commands = f"{ns}/planner/trajectory", f"{ns}/servo/x/command"
    with TopicProbe({commands: AxisCommand, "/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(ServoNode, params, namespace=ns) as servo:
        js_pub = probe.publisher(JointState, f"{ns}/joint_states")
        pub = probe.node.create_publisher(JointTrajectory, topic, 10)
        probe.wait_for(lambda: pub.get_subscription_count() > 0 and js_pub.get_subscription_count() > 0, 10.0,
                       "the servo's readers")
        pub.publish(inputs.trajectory(["x", "y"], [[0.0, 0.0], [2e-3, 0.0]]))
        probe.wait_for(lambda: inputs.refusals(probe, topic), 10.0, "the refusal on /diagnostics")
        pub.publish(inputs.trajectory(["x", "y"], [[0.0, 0.0], [5e-4, 0.0]]))
        probe.wait_for(lambda: servo.node.trajectory.received == 1, 10.0, "the trajectory inside")
        for k in range(8):
            js_pub.publish(inputs.joint_state(k))
        probe.wait_for(lambda: len(probe.received(commands)) == 8, 10.0, "8 commands")
        assert not servo.node.finished and servo.node.fault_message is None
    first = inputs.refusals(probe, topic)[0]
    assert first.level == DiagnosticStatus.WARN and inputs.values(first)["refused_count"] == "1"
    assert "point 1 takes axis x to 2.000000 mm, 1.000000 mm beyond its travel_max_mm 1" in first.message
    assert max(abs(m.command) for m in probe.received(commands)) > 0.0, "the trajectory inside drives the axis"


def test_a_program_file_leaving_the_travel_is_refused_at_configure_naming_line_axis_and_excess(tmp_path) -> None:
    program = tmp_path / "part.ngc"
    program.write_text("G1 X5 F1200\nG2 X5 Y-6 I0 J-3\n")  # the half circle reaches x 8
    params = {"axes": ["x", "y"], "program_file": str(program), "travel_min_mm": [-1.0, -10.0],
              "travel_max_mm": [7.5, 10.0]}
    with pytest.raises(CncError, match=r"line 2 takes axis x to 8\.000000 mm, 0\.500000 mm beyond its "
                                       r"travel_max_mm 7\.5"):
        with InProcessNode(InterpolatorNode, params, namespace=f"/travel_{uuid.uuid4().hex[:8]}"):
            pass
