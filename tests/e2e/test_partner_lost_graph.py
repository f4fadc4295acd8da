"""Tier 3: a servo process killed mid-run: the plant stops the machine and faults naming it (real graph).

A servo that exits (SIGTERM, or its own fault) leaves the ROS graph at once: the plant sees its command
topic without publishers. A crashed one (SIGKILL) stays in the graph until its DDS lease expires (Fast DDS:
20 s), so the plant's command timeout finds it first, naming the node that last published the topic.
"""
from __future__ import annotations

import json
import os
import signal
import time
import uuid
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState

from cnc_contour_control.testing import TopicProbe
from cnc_contour_interfaces.msg import AxisCommand, Reference
from cnc_tools.runs.graph import GraphRun
from cnc_tools.runs.graph_nodes import PLANT_TIMEOUT_FACTOR, graph_nodes
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
#: Each run in a namespace of its own (also a repeat of a case): a servo killed by SIGKILL stays in the graph
#: until its DDS lease ends.
NS_PREFIX = "/cnc/partner_lost_e2e_"
#: The stages' input timeout in this run [s] ...
INPUT_TIMEOUT_S = 1.0
#: ... and the plant's per-tick command timeout it gives.
COMMAND_TIMEOUT_S = PLANT_TIMEOUT_FACTOR * INPUT_TIMEOUT_S

pytestmark = pytest.mark.e2e


#: (signal, how the plant's fault starts, the bound on its exit after the kill [s]).
CASES = {
    "exits": (signal.SIGTERM, "plant: {ns}/servo_y left the graph: {ns}/servo/y/command has 0 publishers (had 1)",
              COMMAND_TIMEOUT_S),  # sooner than the timeout: found in the graph
    "crashes": (signal.SIGKILL, "plant: no {ns}/servo/y/command (last published by {ns}/servo_y) for tick t=",
                COMMAND_TIMEOUT_S + 3.0),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_killing_a_servo_mid_run_stops_the_plant_with_a_fault_naming_it(tmp_path: Path, case: str) -> None:
    sig, fault, bound_s = CASES[case]
    ns = f"{NS_PREFIX}{case}_{uuid.uuid4().hex[:8]}"
    fault = fault.format(ns=ns)
    scenario = load_scenario(CIRCLE, {"duration_s": 200.0})  # the kill ends it; mid-run however fast the graph runs
    probed = {f"{ns}/joint_states": JointState, f"{ns}/reference": Reference, f"{ns}/diagnostics": DiagnosticArray,
              f"{ns}/servo/x/command": AxisCommand, f"{ns}/servo/y/command": AxisCommand}
    with TopicProbe(probed) as probe, GraphRun(graph_nodes(scenario, tmp_path, 1, INPUT_TIMEOUT_S), tmp_path,
                                               namespace=ns) as run:
        def ticks() -> int:
            return len(probe.received(f"{ns}/joint_states"))

        probe.wait_for(lambda: ticks() > 50, 120.0, "50 ticks of the run")
        pid = json.loads((tmp_path / "pids.json").read_text())["nodes"]["servo_y"]
        os.kill(pid, sig)
        killed_s = time.monotonic()
        probe.wait_for(lambda: run.exit_codes()["plant"] is not None, bound_s + 5.0, "the plant's exit")
        stopped_after_s = time.monotonic() - killed_s
        codes = run.exit_codes()  # as the plant ends: servo_x still runs
        # servo_y left the graph before its process ended, so the plant may have ended first
        probe.wait_for(lambda: run.exit_codes()["servo_y"] is not None, 10.0, "servo_y's exit")
        codes["servo_y"] = run.exit_codes()["servo_y"]
        ticks_at_exit = ticks()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert codes["plant"] == 3 and codes["servo_x"] is None and codes["servo_y"] is not None
    assert stopped_after_s < bound_s, f"the plant stopped {stopped_after_s:.2f} s after the kill"
    assert summary["status"] == "faulted" and len(summary["faults"]) == 1 and summary["faults"][0].startswith(fault)
    assert summary["estop_latches"] == 1 and ticks_at_exit < 2000, "stopped mid-run (20 s are 2001 ticks)"
    errors = [s for a in probe.received(f"{ns}/diagnostics") for s in a.status
              if s.level == DiagnosticStatus.ERROR and s.name == f"{ns}/plant"]
    assert [s.message for s in errors] == summary["faults"], "the fault on /diagnostics"
