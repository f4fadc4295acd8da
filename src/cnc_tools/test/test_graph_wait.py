"""Tier 2: the runner's wait names the cause of a run's end (real processes standing in for the nodes, no ROS).

A partner that faults leaves the ROS graph at once but its interpreter ends later, so the plant, which faults
"<partner> left the graph", may end first. The partner's own fault is the cause, not the plant's.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from cnc_tools.runs.compose import ProcessGroup
from cnc_tools.runs.graph import GraphRun, NodeDied
from cnc_tools.runs.graph_nodes import NodeSpec

NS = "/cnc/wait_test"
NODES = ("plant", "servo_x", "servo_y")


def _plant(summary: Path, fault: str) -> str:
    """The plant: writes its faulted summary and exits 3 at once."""
    text = json.dumps({"status": "faulted", "faults": [fault]})
    return f"import pathlib, sys; pathlib.Path({str(summary)!r}).write_text({text!r}); print('FAULT'); sys.exit(3)"


#: A servo that faulted: it prints its fault and ends after its (slow) teardown.
LATE_FAULT = "import sys, time; print('FAULT: joint_states stamped from outside the run', flush=True); " \
             "time.sleep(0.5); sys.exit(3)"
#: A servo that ends cleanly after a while, and one that runs on.
LATE_CLEAN = "import time; time.sleep(0.5)"
RUNS_ON = "import time; time.sleep(600)"


class StandIns(GraphRun):
    """A GraphRun whose node processes are the given Python one-liners."""

    def __init__(self, run_dir: Path, programs: dict[str, str]) -> None:
        super().__init__([NodeSpec("pkg", name, name, {}) for name in NODES], run_dir, env={}, namespace=NS)
        self.programs = programs

    def _command(self, group: ProcessGroup) -> list[str]:
        return [sys.executable, "-c", self.programs[group.name]]


def _run(tmp_path: Path, plant_fault: str, servo_x: str) -> dict[str, int | None]:
    programs = {"plant": _plant(tmp_path / "summary.json", plant_fault), "servo_x": servo_x, "servo_y": RUNS_ON}
    with StandIns(tmp_path, programs) as run:
        return run.wait("plant", 60.0)


def test_a_partner_the_plants_fault_says_left_is_named_though_its_process_ends_after_the_plant(
        tmp_path: Path) -> None:
    with pytest.raises(NodeDied) as died:
        _run(tmp_path, f"plant: {NS}/servo_x left the graph: {NS}/servo/x/command has 0 publishers (had 1)",
             LATE_FAULT)
    assert died.value.node == "servo_x"
    assert "exited with code 3" in str(died.value) and "outside the run" in str(died.value)


def test_the_plants_own_fault_or_a_partner_that_ends_cleanly_is_no_partners_death(tmp_path: Path) -> None:
    codes = _run(tmp_path / "own", "plant: late share 0.3 exceeds max_late_share 0.25", LATE_FAULT)
    assert codes["plant"] == 3 and codes["servo_x"] is None, "not waited for: no fault names it"
    codes = _run(tmp_path / "clean", f"plant: {NS}/servo_x left the graph: {NS}/servo/x/command has 0 publishers "
                                     "(had 1)", LATE_CLEAN)
    assert codes["plant"] == 3 and codes["servo_x"] == 0 and codes["servo_y"] is None


def test_only_the_named_node_counts_not_one_whose_name_it_begins_with(tmp_path: Path) -> None:
    codes = _run(tmp_path, f"plant: {NS}/servo_xy left the graph: {NS}/servo/xy/command has 0 publishers (had 1)",
                 LATE_FAULT)
    assert codes["servo_x"] is None
