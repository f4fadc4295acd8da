"""Tier 2: homing and travel limits on the interpolator in action mode, in-process with real rclpy.

The test ticks a perfect machine (each joint state the previous reference,
``test_program_goals_node.Machine``). With ``require_homing`` a goal ends
REJECTED "axis x is not homed; call home first"; the ``home`` service moves
the axes, one at a time, to the home position through the reference and the
homed state turns true on ``/diagnostics``; a goal leaving the travel ends
REJECTED naming line, axis and excess before any axis moved; one inside runs.
"""
from __future__ import annotations

import uuid

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.action import ActionClient
from std_srvs.srv import Trigger

from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.testing import InProcessNode, TopicProbe, sibling_module
from cnc_contour_interfaces.action import RunProgram
from cnc_contour_interfaces.msg import Reference

pytestmark = pytest.mark.nodes
_GOALS = sibling_module(__file__, "test_program_goals_node")
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
        client = ActionClient(probe.node, RunProgram, f"{ns}/run_program")
        probe.wait_for(client.server_is_ready, 20.0, "the RunProgram server")
        machine = _GOALS.Machine(probe, ns)
        probe.wait_for(lambda: machine.pub.get_subscription_count() > 0, 20.0, "the joint_states reader")
        machine.position_m = [0.004, 0.003]
        unhomed = _GOALS.run_goal(machine, client, RunProgram.Goal(gcode="G1 X5 F1200"))
        assert unhomed.outcome == RunProgram.Result.REJECTED
        assert unhomed.reason == "axis x is not homed; call home first"
        probe.wait_for(lambda: any(v["homed.x"] == "false" for _, v in homed_states(probe, ns)), 10.0,
                       "the homed state on /diagnostics")
        assert homed_states(probe, ns)[-1][0] == int.from_bytes(DiagnosticStatus.WARN, "little")
        answer = probe.call(Trigger, f"{ns}/home", Trigger.Request())
        assert answer.success and "homing started: 2 moves" in answer.message, answer.message
        busy = probe.call(Trigger, f"{ns}/home", Trigger.Request())
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
        assert "line 2 takes axis x to 12.0000 mm, 2.0000 mm beyond its travel_max_mm 10" in outside.reason
        assert machine.position_m == before and outside.ticks == 0
        inside = _GOALS.run_goal(machine, client, RunProgram.Goal(gcode="G1 X5 F1200\nG2 X9 Y1 R2\n"))
        assert inside.outcome == RunProgram.Result.COMPLETED, inside.reason
        touching = _GOALS.run_goal(machine, client, RunProgram.Goal(gcode="G3 X5 Y1 I-2 J0 F1200\nG3 X9 Y1 I2 J0\n"))
        assert touching.outcome == RunProgram.Result.COMPLETED, touching.reason  # its lowest point is y -1 exactly
        deep = _GOALS.run_goal(machine, client, RunProgram.Goal(gcode="G91 G2 X-6 Y0 I-3 J0 F1200\n"))
        assert deep.outcome == RunProgram.Result.REJECTED  # the half circle dips to y -2: ends inside, arc not
        assert "line 1 takes axis y to -2.0000 mm, 1.0000 mm beyond its travel_min_mm -1" in deep.reason

