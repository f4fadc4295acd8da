"""Tier 1: the rows of the verdict table (docs/design.md §5) that an engine run or a recorded bag can show.

The graph's rows (e-stop, late commands, a dead node, a signal) are in tests/e2e; each row here runs the engine
on a shipped scenario or judges a bag whose positions were made to end short.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from cnc_tools.analysis.verdict import END_TOLERANCE_M, judge
from cnc_tools.bagio.synthetic import Trajectory, circle_program, circle_trajectory, write_run_bag
from cnc_tools.cli.main import main
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.outputs import judge_bag
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
NEURAL = ROOT / "scenarios" / "paper001_circle_neural.yaml"
N = 300


def _finished_bag(folder: Path, traj: Trajectory) -> Path:
    """A recorded synthetic circle with the plant's summary of a finished lockstep run beside it."""
    (folder / "summary.json").write_text(json.dumps({"status": "finished", "ticks": N, "faults": [],
                                                     "mode": "lockstep", "sample_time_s": 0.001}))
    return write_run_bag(folder / "bag", circle_program(), traj)


def test_an_engine_run_of_a_shipped_scenario_is_complete() -> None:
    record = run_engine(load_scenario(CIRCLE))
    verdict = judge(record)
    assert verdict.complete, verdict.describe()
    assert bool(record.reference.done[-1]), "the program ended"


def test_a_tripped_learning_guard_faults_the_engine_run() -> None:
    """Paper 001's guard pins the output and stops learning; the run goes on, but it did not run as asked."""
    scenario = load_scenario(NEURAL, {"compensator": {"params": {"eta": 1.0e3, "output_limit": 1.0,
                                                                  "pinned_ticks": 3}}})
    record = run_engine(scenario)
    verdict = judge(record)
    assert verdict.status == "faulted", verdict.describe()
    assert "the compensator's guard stopped it" in verdict.describe() and "learning stopped" in verdict.describe()


@pytest.fixture(scope="module")
def cut() -> RunRecord:
    """The circle with a duration of its own, 2 s of its 6 s program."""
    return run_engine(load_scenario(CIRCLE, {"duration_s": 2.0}))


def test_a_program_cut_short_is_partial_unless_the_run_ends_by_its_duration(cut: RunRecord) -> None:
    assert cut.summary["ends_by"] == "duration" and not bool(cut.reference.done[-1])
    assert judge(cut).complete, "a run told to end at its duration_s may cut its program"
    by_program = dataclasses.replace(cut, summary={**cut.summary, "ends_by": "program"})
    verdict = judge(by_program)
    assert verdict.status == "partial" and "the program did not finish: the reference stood at" in verdict.describe()


@pytest.mark.parametrize("short_m", [2 * END_TOLERANCE_M, 0.037])
def test_axes_short_of_the_programs_end_make_a_partial_verdict(tmp_path: Path, short_m: float,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    """The e-stop finding: the reference ended the program, the axes stood 37 mm short, and the run said COMPLETE."""
    traj = circle_trajectory(0.02, 0.0, n=N)
    # the last sample still short_m or more from the end (the circle is closed: its start is its end)
    stop = int(np.flatnonzero(np.linalg.norm(traj.reference_m - traj.reference_m[-1], axis=1) >= short_m)[-1])
    position = traj.position_m.copy()
    position[stop:] = traj.reference_m[stop] + (position[stop] - traj.reference_m[stop])  # frozen where it stopped
    bag = _finished_bag(tmp_path, dataclasses.replace(traj, position_m=position))
    _, verdict = judge_bag(bag)
    assert verdict.status == "partial", verdict.describe()
    assert "the program did not finish: axis" in verdict.describe() and "from the program's end point" in \
        verdict.describe()
    assert main(["score", str(bag), "--out", str(tmp_path / "out")]) == 1
    assert "the program did not finish" in capsys.readouterr().err, "score refuses it, naming why"


def test_axes_at_the_programs_end_are_complete(tmp_path: Path) -> None:
    _, verdict = judge_bag(_finished_bag(tmp_path, circle_trajectory(0.02, 3e-6, n=N)))
    assert verdict.complete, verdict.describe()


@pytest.fixture(scope="module")
def whole() -> RunRecord:
    """The circle run to its end (ends by its program)."""
    return run_engine(load_scenario(CIRCLE))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.floats(-2e-3, 2e-3), min_size=2, max_size=2))
def test_the_end_verdict_holds_exactly_when_every_axis_is_within_the_tolerance(whole: RunRecord,
                                                                               offset_m: list[float]) -> None:
    """Any last position: complete iff every axis ends within END_TOLERANCE_M of the program's end point."""
    assume(all(abs(abs(o) - END_TOLERANCE_M) > 1e-12 for o in offset_m))  # not on the bound (float sums)
    positions = whole.joint_states.position_m.copy()
    positions[-1] = np.asarray(whole.program.end_m, float) + np.asarray(offset_m)
    record = dataclasses.replace(whole, joint_states=dataclasses.replace(whole.joint_states, position_m=positions))
    verdict = judge(record)
    inside = all(abs(o) <= END_TOLERANCE_M for o in offset_m)
    assert verdict.complete == inside, (offset_m, verdict.describe())
    if not inside:
        assert verdict.status == "partial" and "from the program's end point" in verdict.describe()
