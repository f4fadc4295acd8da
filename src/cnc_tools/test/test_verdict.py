"""A run's verdict comes from the run: its end, per-tick stamps, faults, non-finite samples (``score`` refuses the
rest)."""
from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest

from cnc_contour_control.core import topics as t
from cnc_tools.analysis.verdict import Status, judge
from cnc_tools.bagio.bag import BagWriter
from cnc_tools.bagio.synthetic import (
    COMMAND_TYPE,
    TOPICS,
    Trajectory,
    axis_command,
    circle_program,
    circle_trajectory,
    header,
    joint_state,
    path_message,
    reference,
)
from cnc_tools.bagio.typestore import project_typestore
from cnc_tools.cli.main import main
from cnc_tools.runs.outputs import judge_bag

N = 300
FINISHED = {"status": "finished", "ticks": N, "faults": [], "mode": "lockstep", "sample_time_s": 0.001}


def _status(level: int, message: str, values: dict[str, str] | None = None, name: str = "/cnc/plant") -> object:
    types = project_typestore().types
    kvs = [types["diagnostic_msgs/msg/KeyValue"](key=k, value=v) for k, v in (values or {}).items()]
    return types["diagnostic_msgs/msg/DiagnosticStatus"](level=level, name=name, message=message,
                                                           hardware_id="cnc_contour", values=kvs)


def _run_folder(root: Path, traj: Trajectory | None = None, summary: dict | None = None,
                statuses: Sequence[object] = (), skip: Sequence[int] = (), diagnostics: str = "/diagnostics") -> Path:
    """A run folder: ``bag/`` (path, joint states, references, commands, statuses) and ``summary.json`` if given."""
    program = circle_program()
    traj = traj or circle_trajectory(0.02, 3e-6, n=N)
    topics = {**TOPICS, **{f"/cnc/servo/{a}/command": COMMAND_TYPE for a in program.axis_names},
              diagnostics: t.DIAGNOSTICS.type_name}
    store = project_typestore()
    with BagWriter(root / "bag", topics) as writer:
        writer.write_message("/cnc/path", 0, path_message(program))
        for k, stamp in enumerate(traj.stamp_ns.tolist()):
            writer.write_message("/cnc/joint_states", stamp, joint_state(stamp, program.axis_names, traj.position_m[k],
                                                                         traj.reference_velocity_m_s[k]))
            if k not in skip:
                writer.write_message("/cnc/reference", stamp, reference(stamp, program.axis_names, traj.reference_m[k],
                                                                        traj.reference_velocity_m_s[k],
                                                                        done=k == len(traj.stamp_ns) - 1))
            for axis in program.axis_names:
                writer.write_message(f"/cnc/servo/{axis}/command", stamp, axis_command(stamp, axis, 1.0, 0.0))
        if statuses:
            array = store.types["diagnostic_msgs/msg/DiagnosticArray"](header=header(0, ""), status=list(statuses))
            writer.write_message(diagnostics, int(traj.stamp_ns[-1]), array)
    if summary is not None:
        (root / "summary.json").write_text(json.dumps(summary))
    return root / "bag"


def _finished(ticks: int = N) -> object:
    return _status(0, t.RUN_FINISHED, {t.TICKS_KEY: str(ticks)})


def test_a_finished_run_with_every_tick_is_complete_and_scored(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    bag = _run_folder(tmp_path, summary=FINISHED, statuses=[_finished()])
    _, verdict = judge_bag(bag)
    assert verdict.complete and verdict.ticks == N, verdict.describe()
    assert main(["score", str(bag), "--out", str(tmp_path / "out")]) == 0
    assert "verdict: COMPLETE (300 ticks" in capsys.readouterr().out
    (score_json,) = (tmp_path / "out").glob("*/score.json")
    assert json.loads(score_json.read_text())["verdict"]["status"] == "complete"


@pytest.mark.parametrize(("summary", "statuses", "expected"), [
    (None, [_finished()], "complete"),                      # the run-finished status alone tells the end
    (FINISHED, [], "complete"),                             # the plant's summary alone too
    (None, [], "the run's end is not recorded"),
    ({**FINISHED, "status": "running", "ticks": 57}, [], "summary.json: 'running' after 57 ticks"),
    ({**FINISHED, "status": "interrupted", "reason": "interrupted by SIGTERM"}, [], "interrupted by SIGTERM"),
    ({**FINISHED, "ticks": 4000}, [], "/cnc/joint_states holds 300 messages for 4000 ticks"),
    (FINISHED, [_finished(301)], "announced with different tick counts [300, 301]"),
])
def test_the_end_of_the_run_decides(tmp_path: Path, summary: dict | None, statuses: list, expected: str) -> None:
    _, verdict = judge_bag(_run_folder(tmp_path, summary=summary, statuses=statuses))
    if expected == "complete":
        assert verdict.complete, verdict.describe()
    else:
        assert verdict.status == "partial" and expected in verdict.describe(), verdict.describe()


def test_a_5_7_s_prefix_of_a_40_s_run_is_refused_unless_allowed(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The bag's own index is intact; the run behind it is not."""
    bag = _run_folder(tmp_path, summary={**FINISHED, "status": "interrupted", "ticks": 570, "reason": "SIGKILL"})
    assert main(["score", str(bag)]) == 1
    captured = capsys.readouterr()
    assert captured.out == "" and len(captured.err.strip().splitlines()) == 1
    assert "error:" in captured.err and "PARTIAL" in captured.err and "--allow-partial" in captured.err
    assert main(["score", str(bag), "--allow-partial"]) == 0
    assert "verdict: PARTIAL: the run did not finish" in capsys.readouterr().out


def test_a_missing_tick_breaks_the_stamps(tmp_path: Path) -> None:
    _, verdict = judge_bag(_run_folder(tmp_path, summary=FINISHED, skip=[150]))
    assert verdict.status == "partial"
    assert "/cnc/reference holds 299 messages for 300 ticks" in verdict.reasons
    assert any("/cnc/reference stamps are not contiguous: 1 jumps, the first from t = 0.150000 s" in r
               for r in verdict.reasons), verdict.reasons


@pytest.mark.parametrize("where", ["summary", "diagnostics"])
def test_faults_make_the_run_faulted(tmp_path: Path, where: str) -> None:
    message = "servo_y: no /cnc/reference for tick t=0.120000 s within 5.0 s"
    summary = {**FINISHED, "status": "faulted", "faults": [message]} if where == "summary" else FINISHED
    statuses = [_status(2, message, name="/cnc/servo_y")] if where == "diagnostics" else []
    _, verdict = judge_bag(_run_folder(tmp_path, summary=summary, statuses=statuses))
    assert verdict.status == "faulted" and message in verdict.describe()
    assert verdict.describe().count(message) == 1


def test_statuses_in_the_runs_namespace_are_read(tmp_path: Path) -> None:
    bag = _run_folder(tmp_path, statuses=[_finished()], diagnostics="/cnc/run_1234abcd/diagnostics")
    _, verdict = judge_bag(bag)
    assert verdict.complete, verdict.describe()


def test_statuses_of_another_run_id_are_not_this_runs(synth) -> None:
    run = synth.make_run(synth.circle_program(), synth.circle_trajectory(0.02, 1e-6, n=50))
    run = run.with_(summary={"status": "finished", "ticks": 50, t.RUN_ID_KEY: "run_a"})
    foreign = Status(2, "/cnc/plant", "plant: fault of another run", {t.RUN_ID_KEY: "run_b"})
    own = Status(2, "/cnc/plant", "plant: our fault", {t.RUN_ID_KEY: "run_a"})
    assert judge(run, [foreign]).status == "partial"  # the synthetic run has no commands: partial, not faulted
    both = judge(run, [foreign, own])
    assert both.status == "faulted" and "/cnc/plant: plant: our fault" in both.reasons
    assert "another run" not in both.describe()


def test_a_recorded_nan_is_reported_with_its_time_and_topic_not_a_traceback(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    traj = circle_trajectory(0.02, 3e-6, n=N)
    traj.position_m[120:125, 1] = np.nan
    bag = _run_folder(tmp_path, traj, summary=FINISHED)
    assert main(["score", str(bag)]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "FAULTED: non-finite position on /cnc/joint_states at t = 0.121000 s (5 samples)" in err
    assert main(["score", str(bag), "--allow-partial"]) == 0
    out = capsys.readouterr().out
    assert "5 samples with a non-finite position not scored" in out and "verdict: FAULTED" in out


def test_nan_in_the_reference_and_everywhere_is_scored_without_error(synth) -> None:
    from cnc_tools.analysis.scoring import score_run

    traj = synth.circle_trajectory(0.02, 3e-6, n=200)
    traj.reference_m[50] = np.nan
    traj.reference_velocity_m_s[50] = np.nan
    run = synth.make_run(synth.circle_program(), traj)
    assert [n.topic for n in judge(run).non_finite] == ["/cnc/reference"]
    score = score_run(run)
    assert score.tracking[0].n_samples == 199 and np.isfinite(score.contour.values_si["max"])
    traj.position_m[:] = np.nan
    empty = score_run(synth.make_run(synth.circle_program(), traj))
    assert empty.window.n_scored == 0 and empty.window.n_non_finite == 200


def test_an_engine_record_is_judged_by_its_own_summary() -> None:
    from cnc_tools.runs.engine import run_engine
    from cnc_tools.runs.scenario import load_scenario

    scenario = load_scenario(Path(__file__).resolve().parents[3] / "scenarios" / "paper000_circle_high.yaml",
                             {"duration_s": 0.3})
    record = run_engine(scenario)
    assert judge(record).complete, judge(record).describe()
    cut = record.with_(reference=None)
    assert "/cnc/reference holds 0 messages for 31 ticks" in judge(cut).reasons


def test_a_stale_status_is_no_fault_but_an_error_is(synth) -> None:
    run = synth.make_run(synth.circle_program(), synth.circle_trajectory(0.02, 1e-6, n=50))
    run = run.with_(summary={"status": "finished", "ticks": 50, t.RUN_ID_KEY: "run_a"})
    stale = Status(3, "/cnc/servo_x", "waiting for /cnc/joint_states: 0 of 1 publishers", {t.RUN_ID_KEY: "run_a"})
    error = Status(2, "/cnc/servo_x", "servo_x: no /cnc/reference", {t.RUN_ID_KEY: "run_a"})
    assert judge(run, [stale]).status == "partial", "the synthetic run has no commands: partial, not faulted"
    assert judge(run, [stale, error]).status == "faulted"


def test_score_out_names_each_runs_folder_by_the_run_and_keeps_two_of_one_name_apart(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    # two copies of one run: one name (its folder and the folder above), and each file's folder is "bag"
    bags = [_run_folder(tmp_path / side / "runs" / "same", summary=FINISHED, statuses=[_finished()])
            for side in ("a", "b")]
    mcaps = [next(bag.glob("*.mcap")) for bag in bags]
    assert main(["score", *map(str, mcaps), "--out", str(tmp_path / "out")]) == 0
    capsys.readouterr()
    folders = sorted(p.parent.name for p in (tmp_path / "out").glob("*/score.json"))
    assert folders == ["runs_same", "runs_same-2"], folders
