"""Tier 2: the plant node's e-stop latch, enable/reset services and command watchdog, in-process with real rclpy."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, Trigger

from cnc_contour_control.nodes.common import ns_to_stamp, stamp_to_ns
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import AxisCommand
from cnc_plant_sim.nodes.plant_node import PlantNode

pytestmark = pytest.mark.nodes
T_NS = 10_000_000
PARAMS = {"axes": ["x"], "sample_time_s": 0.01, "duration_s": 2.0, "expected_subscribers": 1,
          "command_timeout_s": 30.0}
PROBED = {"/cnc/joint_states": JointState, "/diagnostics": DiagnosticArray}


def command(stamp_ns: int, value: float) -> AxisCommand:
    msg = AxisCommand(axis_name="x", command=value, command_unit="dac")
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


def call(probe: TopicProbe, srv_type: type, name: str, request: Any) -> Any:
    """Call a service of the plant from the probe's node and wait for the answer."""
    return probe.call(srv_type, name, request)


def run_ticks(probe: TopicProbe, pub: Any, first: int, last: int, value: float) -> list[float]:
    """Answer ticks first..last with ``value``; the x velocity at each tick's stamp."""
    velocities = []
    for k in range(first, last + 1):
        probe.wait_for(lambda k=k: len(probe.received("/cnc/joint_states")) > k, 10.0, f"tick {k}")
        state = probe.received("/cnc/joint_states")[k]
        assert stamp_to_ns(state.header.stamp) == k * T_NS
        velocities.append(state.velocity[0])
        pub.publish(command(k * T_NS, value))
    return velocities


def statuses(probe: TopicProbe) -> list[Any]:
    return [s for array in probe.received("/diagnostics") for s in array.status]


def test_estop_zeroes_commands_latches_refuses_enable_and_resets_once_released() -> None:
    with TopicProbe(PROBED) as probe:
        pub = probe.publisher(AxisCommand, "/cnc/servo/x/command")
        estop = probe.node.create_publisher(Bool, "/cnc/estop", 10)
        with InProcessNode(PlantNode, PARAMS) as plant:
            driven = run_ticks(probe, pub, 0, 9, 100.0)
            probe.wait_for(lambda: estop.get_subscription_count() > 0, 10.0, "the plant's estop subscription")
            estop.publish(Bool(data=True))
            probe.wait_for(lambda: plant.node.latch.latched, 10.0, "the latch")
            stopped = run_ticks(probe, pub, 10, 39, 100.0)
            estop.publish(Bool(data=False))
            probe.wait_for(lambda: not plant.node.latch.estop_input, 10.0, "the input released")
            refused = call(probe, SetBool, "/cnc/plant/enable", SetBool.Request(data=True))
            reset = call(probe, Trigger, "/cnc/plant/reset", Trigger.Request())
            enabled = call(probe, SetBool, "/cnc/plant/enable", SetBool.Request(data=True))
            resumed = run_ticks(probe, pub, 40, 49, 100.0)
    assert driven[-1] > driven[1] > 0.0, "driven: the axis speeds up"
    assert stopped[-1] < 0.5 * stopped[1], "latched: zero command, the axis coasts down though the servo sends 100"
    assert not refused.success and "e-stop latched" in refused.message and "/cnc/estop" in refused.message
    assert reset.success and enabled.success
    assert resumed[-1] > resumed[0], "enabled again: the commands reach the drive"
    latched = [s for s in statuses(probe) if s.message.startswith("e-stop latched")]
    assert len(latched) == 1 and latched[0].level == DiagnosticStatus.WARN
    assert {kv.key: kv.value for kv in latched[0].values}["estop_latched"] == "true"


def test_reset_is_refused_while_the_estop_input_is_true() -> None:
    with TopicProbe(PROBED) as probe:
        probe.publisher(AxisCommand, "/cnc/servo/x/command")
        estop = probe.node.create_publisher(Bool, "/cnc/estop", 10)
        with InProcessNode(PlantNode, PARAMS) as plant:
            probe.wait_for(lambda: estop.get_subscription_count() > 0, 20.0, "the plant's estop subscription")
            estop.publish(Bool(data=True))
            probe.wait_for(lambda: plant.node.latch.latched, 10.0, "the latch")
            answer = call(probe, Trigger, "/cnc/plant/reset", Trigger.Request())
            assert plant.node.latch.latched
    assert not answer.success and "still true" in answer.message


def test_realtime_run_whose_commands_never_arrive_faults_on_the_late_share(tmp_path: Path) -> None:
    summary_file = tmp_path / "summary.json"
    params = {**PARAMS, "mode": "realtime", "max_late_share": 0.2, "late_share_min_ticks": 20,
              "command_max_age_s": 0.03, "summary_file": str(summary_file)}
    with TopicProbe(PROBED) as probe:
        pub = probe.publisher(AxisCommand, "/cnc/servo/x/command")  # closes the loop, then misses every deadline
        with InProcessNode(PlantNode, params) as plant:
            run_ticks(probe, pub, 0, 0, 0.0)
            probe.wait_for(lambda: plant.node.finished, 20.0, "the fault")
            probe.wait_for(lambda: any(s.level == DiagnosticStatus.ERROR for s in statuses(probe)), 10.0,
                           "the fault on /diagnostics")
    summary = json.loads(summary_file.read_text())
    assert summary["status"] == "faulted" and summary["ticks"] == 19, "judged at the 20th tick"
    assert "19 of 20 commands late" in summary["faults"][0] and "max_late_share 0.2" in summary["faults"][0]
    assert summary["late_commands"] == 19, "tick 0's command closed the loop"
    assert 15 <= summary["held_commands"] <= 18, "zero once 30 ms old (stamps follow the measured periods)"


def test_realtime_clock_waits_for_the_loop_to_close_and_faults_naming_the_silent_command_topic(tmp_path: Path) -> None:
    summary_file = tmp_path / "summary.json"
    params = {**PARAMS, "mode": "realtime", "command_timeout_s": 0.2, "startup_timeout_s": 0.5,
              "summary_file": str(summary_file)}
    with TopicProbe(PROBED) as probe:
        probe.publisher(AxisCommand, "/cnc/servo/x/command")  # matched, never answers tick 0
        with InProcessNode(PlantNode, params) as plant:
            probe.wait_for(lambda: plant.node.finished, 20.0, "the fault")
            assert not plant.node.loop_closed
    summary = json.loads(summary_file.read_text())
    assert summary["status"] == "faulted" and summary["ticks"] == 0, "the wall clock never started"
    assert "no /cnc/servo/x/command (last published by /probe) for tick t=0.000000 s within 0.5 s" in \
        summary["faults"][0], summary["faults"]
    assert summary["late_commands"] == 0
