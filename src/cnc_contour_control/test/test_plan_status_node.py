"""Tier 2: the interpolator node reports a streaming plan's state on /diagnostics (real rclpy, one node)."""
from __future__ import annotations

from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.nodes.interpolator_node import PLAN_STATUS, InterpolatorNode
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import Reference

pytestmark = pytest.mark.nodes

SEGMENTS = 3000
WINDOW = 40
T_NS = 1_000_000


def zigzag(path: Path) -> Path:
    """``SEGMENTS`` short lines, 0.4 mm each, 14 degree turns: about 55 s at the feed, many windows long."""
    lines = ["G90 G21 G64 P0.01", "G1 X0 Y0 F1300"]
    lines += [f"G1 X{0.4 * (k + 1):.4f} Y{0.05 * (k % 2):.4f}" for k in range(SEGMENTS)]
    path.write_text("\n".join(lines) + "\n")
    return path


def plan_statuses(probe: TopicProbe) -> list[DiagnosticStatus]:
    return [s for array in probe.received("/diagnostics") for s in array.status if s.message == PLAN_STATUS]


def test_a_streaming_plan_reports_its_waits_rows_and_lead(tmp_path: Path) -> None:
    params = {"axes": ["x", "y"], "program_file": str(zigzag(tmp_path / "zigzag.ngc")),
              "feed_override_source": "schedule", "feed_override.schedule_times_s": [0.0],
              "feed_override.schedule_ratios": [1.0], "look_ahead_segments": WINDOW,
              "max_velocity_m_s": [0.05, 0.05], "max_acceleration_m_s2": [0.5, 0.5]}
    with TopicProbe({"/cnc/reference": Reference, "/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(InterpolatorNode, params) as interpolator:
        live = interpolator.node.live
        assert live is not None and live.planner is not None, "it streams"
        ticks = probe.publisher(JointState, "/cnc/joint_states")
        probe.wait_for(lambda: ticks.get_subscription_count() > 0, 10.0, "the interpolator's reader")
        for k in range(200):  # one tick per reference: the node answers each joint state in turn
            header = Header(stamp=ns_to_stamp(k * T_NS), frame_id="machine")
            ticks.publish(JointState(name=["x", "y"], position=[0.0, 0.0], header=header))
            probe.wait_for(lambda k=k: len(probe.received("/cnc/reference")) > k, 10.0, f"reference {k}")
        probe.wait_for(lambda: len(plan_statuses(probe)) >= 1, 10.0, "a streaming plan status")
        waits = live.planner.waits
    status = plan_statuses(probe)[-1]
    values = {v.key: v.value for v in status.values}
    assert status.level == DiagnosticStatus.OK
    assert 0 <= int(values["planner_waits"]) <= waits, "the count so far"
    assert values["plan_finished"] == "false", "200 ms of a 55 s program"
    assert int(values["plan_held_rows"]) > 0
    assert 0.0 < float(values["plan_ahead_s"]) <= 60.0, "planned ahead of the tool, a window's worth"
