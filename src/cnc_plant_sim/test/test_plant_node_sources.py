"""Tier 2: the plant node's JointState command source (= AxisCommand bit for bit) and a commanding node that
leaves mid-run, in-process with real rclpy."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState

from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import AxisCommand
from cnc_plant_sim.nodes.plant_node import PlantNode

pytestmark = pytest.mark.nodes
T_NS = 10_000_000
PARAMS = {"axes": ["x", "y"], "sample_time_s": 0.01, "duration_s": 1.0, "expected_subscribers": 1,
          "command_timeout_s": 30.0}
STATES = "/cnc/joint_states"
PROBED = {STATES: JointState, "/diagnostics": DiagnosticArray}


def value(axis: str, k: int) -> float:
    """A command that differs per axis and tick [DAC]."""
    return (40.0 if axis == "x" else -25.0) + 3.0 * (k % 7)


def axis_command(axis: str, k: int) -> AxisCommand:
    msg = AxisCommand(axis_name=axis, command=value(axis, k), command_unit="dac")
    msg.header.stamp = ns_to_stamp(k * T_NS)
    return msg


def joint_command(axes: list[str], k: int, field: str = "effort") -> JointState:
    msg = JointState(name=axes)
    setattr(msg, field, [value(a, k) for a in axes])
    msg.header.stamp = ns_to_stamp(k * T_NS)
    return msg


def drive(probe: TopicProbe, ticks: int, send: Any) -> list[tuple[float, ...]]:
    """Answer ``ticks`` ticks with ``send(k)``; the joint positions the plant published."""
    for k in range(ticks):
        probe.wait_for(lambda k=k: len(probe.received(STATES)) > k, 10.0, f"tick {k}")
        send(k)
    probe.wait_for(lambda: len(probe.received(STATES)) > ticks, 10.0, "the last tick")
    return [tuple(m.position) for m in probe.received(STATES)]


def test_joint_state_efforts_drive_the_plant_exactly_as_axis_commands() -> None:
    with TopicProbe(PROBED) as probe:
        pubs = {a: probe.publisher(AxisCommand, f"/cnc/servo/{a}/command") for a in ("x", "y")}
        with InProcessNode(PlantNode, PARAMS):
            reference = drive(probe, 20, lambda k: [pubs[a].publish(axis_command(a, k)) for a in ("x", "y")])
    with TopicProbe(PROBED) as probe:
        pub = probe.publisher(JointState, "/cnc/joint_commands")
        with InProcessNode(PlantNode, {**PARAMS, "command_source": "joint_state"}):
            # one message with both axes on even ticks, one per axis (y first) on odd ones
            def send(k: int) -> None:
                for axes in ([["x", "y"]] if k % 2 == 0 else [["y"], ["x"]]):
                    pub.publish(joint_command(axes, k))

            ours = drive(probe, 20, send)
    assert reference[-1][0] > 0.0 > reference[-1][1], "the commands moved both axes"
    assert ours == reference, "bit for bit"


def test_a_joint_command_with_an_unknown_joint_is_a_fault_naming_it() -> None:
    with TopicProbe(PROBED) as probe:
        pub = probe.publisher(JointState, "/cnc/joint_commands")
        with InProcessNode(PlantNode, {**PARAMS, "command_source": "joint_state"}) as plant:
            probe.wait_for(lambda: len(probe.received(STATES)) == 1, 20.0, "tick 0")
            pub.publish(joint_command(["x", "z"], 0))
            probe.wait_for(lambda: plant.node.finished, 10.0, "the fault")
    message = plant.node.fault_message or ""
    assert message.startswith("/cnc/joint_commands: ") and "unknown joints ['z']" in message
    assert len(probe.received(STATES)) == 1


def test_a_velocity_commanded_plant_reads_the_velocity_field() -> None:
    params = {**PARAMS, "model": "paper002", "command_source": "joint_state"}
    with TopicProbe(PROBED) as probe:
        pub = probe.publisher(JointState, "/cnc/joint_commands")
        with InProcessNode(PlantNode, params) as plant:
            probe.wait_for(lambda: len(probe.received(STATES)) == 1, 20.0, "tick 0")
            pub.publish(joint_command(["x", "y"], 0, field="effort"))  # the wrong field: no values
            probe.wait_for(lambda: plant.node.finished, 10.0, "the fault")
    assert "joint_commands.velocity has 0 values for 2 names" in (plant.node.fault_message or "")


def test_a_commanding_node_leaving_mid_run_stops_the_machine_with_a_fault_naming_it(tmp_path: Path) -> None:
    summary = tmp_path / "summary.json"
    with TopicProbe(PROBED, name="servo_stand_in", namespace="/cnc") as probe:
        pubs = {a: probe.publisher(AxisCommand, f"/cnc/servo/{a}/command") for a in ("x", "y")}
        with InProcessNode(PlantNode, {**PARAMS, "summary_file": str(summary)}) as plant:
            drive(probe, 5, lambda k: [pubs[a].publish(axis_command(a, k)) for a in ("x", "y")])
            watch = plant.node.partners.watch
            probe.wait_for(lambda: watch.publishers("/cnc/servo/y/command") == ("/cnc/servo_stand_in",), 5.0,
                           "the plant to know the publisher by name")
            probe.node.destroy_publisher(pubs["y"])
            probe.wait_for(lambda: plant.node.finished, 5.0, "the plant's fault")  # << command_timeout_s 30 s
    message = plant.node.fault_message or ""
    assert "/cnc/servo_stand_in left the graph: /cnc/servo/y/command has 0 publishers" in message
    assert message.endswith("t=0.050000 s; machine stopped") and plant.node.latch.latched
    errors = [s for a in probe.received("/diagnostics") for s in a.status if s.level == DiagnosticStatus.ERROR]
    assert [s.message for s in errors] == [message]
    written = json.loads(summary.read_text())
    assert written["status"] == "faulted" and written["faults"] == [message] and written["estop_latches"] == 1
