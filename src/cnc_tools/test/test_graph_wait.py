"""Tier 2: the runner's wait names the cause of a run's end (real processes standing in for the nodes, no ROS).

A partner that faults leaves the ROS graph at once but its interpreter ends later, so the plant, which faults
"<partner> left the graph", may end first. The partner's own fault is the cause, not the plant's.
"""
from __future__ import annotations

import json
import sys
from collections.abc import Sequence
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


#: Written by :meth:`StandIns.failed_within` when the runner, having seen the plant end, waits for partners.
WAITING = "partners_waited_for"


#: A servo that faulted: it prints its fault and ends, later than the plant (after its slow teardown).
LATE_FAULT = "print('FAULT: joint_states stamped from outside the run', flush=True); sys.exit(3)"
#: A servo that ends cleanly later than the plant.
LATE_CLEAN = "sys.exit(0)"
#: A servo that runs on.
RUNS_ON = "import time; time.sleep(600)"


def _after_the_runner_waits(run_dir: Path, then: str) -> str:
    """A servo that runs until the runner waits for partners after the plant's end (a condition, not a delay)."""
    waiting = str(run_dir / WAITING)
    return f"import pathlib, sys, time\nwhile not pathlib.Path({waiting!r}).exists(): time.sleep(0.01)\n{then}"


class StandIns(GraphRun):
    """A GraphRun whose node processes are the given Python programs."""

    def __init__(self, run_dir: Path, programs: dict[str, str]) -> None:
        super().__init__([NodeSpec("pkg", name, name, {}) for name in NODES], run_dir, env={}, namespace=NS)
        self.programs = programs
        self.waited_for: list[list[str]] = []

    def _command(self, group: ProcessGroup) -> list[str]:
        return [sys.executable, "-c", self.programs[group.name]]

    def failed_within(self, names: Sequence[str], grace_s: float) -> NodeDied | None:
        """Note whom the runner waits for; the late stand-ins end once it waits for someone."""
        self.waited_for.append(list(names))
        if names:
            (self.run_dir / WAITING).touch()
        return super().failed_within(names, grace_s)


def _run(tmp_path: Path, plant_fault: str, servo_x: str) -> tuple[dict[str, int | None], list[list[str]]]:
    """The exit codes the runner returns, and whom it waited for after the plant ended."""
    programs = {"plant": _plant(tmp_path / "summary.json", plant_fault),
                "servo_x": _after_the_runner_waits(tmp_path, servo_x), "servo_y": RUNS_ON}
    with StandIns(tmp_path, programs) as run:
        return run.wait("plant", 60.0), run.waited_for


def test_a_partner_the_plants_fault_says_left_is_named_though_its_process_ends_after_the_plant(
        tmp_path: Path) -> None:
    with pytest.raises(NodeDied) as died:
        _run(tmp_path, f"plant: {NS}/servo_x left the graph: {NS}/servo/x/command has 0 publishers (had 1)",
             LATE_FAULT)
    assert died.value.node == "servo_x"
    assert "exited with code 3" in str(died.value) and "outside the run" in str(died.value)


def test_the_plants_own_fault_or_a_partner_that_ends_cleanly_is_no_partners_death(tmp_path: Path) -> None:
    codes, waited_for = _run(tmp_path / "own", "plant: late share 0.3 exceeds max_late_share 0.25", LATE_FAULT)
    assert codes["plant"] == 3 and codes["servo_x"] is None and waited_for == [[]], "not waited for: no fault names it"
    codes, waited_for = _run(tmp_path / "clean", f"plant: {NS}/servo_x left the graph: {NS}/servo/x/command has 0 "
                                                 "publishers (had 1)", LATE_CLEAN)
    assert codes["plant"] == 3 and codes["servo_x"] == 0 and codes["servo_y"] is None and waited_for == [["servo_x"]]


def test_only_the_named_node_counts_not_one_whose_name_it_begins_with(tmp_path: Path) -> None:
    codes, waited_for = _run(tmp_path, f"plant: {NS}/servo_xy left the graph: {NS}/servo/xy/command has 0 publishers "
                                       "(had 1)", LATE_FAULT)
    assert codes["servo_x"] is None and waited_for == [[]]
