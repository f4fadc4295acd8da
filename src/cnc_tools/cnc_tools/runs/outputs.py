"""A run's path to people: judge it, score its record, write JSON/CSV and the plots into its run folder.

Every score carries the run's verdict (:mod:`cnc_tools.analysis.verdict`):
a bag is judged with its run folder's ``summary.json`` and its recorded
``/diagnostics``, an engine record with the engine's summary.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from cnc_tools.analysis.scoring import Score, score_run
from cnc_tools.analysis.verdict import Verdict, judge
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.lifetime import read_summary


@dataclass(frozen=True)
class ScoredRun:
    """A run record, its score, and the files written for it."""

    run: RunRecord
    score: Score
    json_path: Path | None = None
    csv_path: Path | None = None

    @property
    def verdict(self) -> Verdict:
        """The run's verdict (complete, partial, faulted)."""
        return self.score.verdict or judge(self.run)


def score_record(run: RunRecord, out_dir: Path | None = None, metrics: Sequence[str] | None = None,
                 verdict: Verdict | None = None, force_reference_n: float | None = None) -> ScoredRun:
    """Score one run record; with ``out_dir``, also write ``score.json`` and ``score.csv`` there.

    ``verdict`` defaults to the record's own (:func:`~cnc_tools.analysis.verdict.judge` of its summary);
    ``force_reference_n`` [N] scores a run that cut against its force reference. An engine record
    written into a run folder is named after it (:func:`named_by_run_folder`).
    """
    run = named_by_run_folder(run, out_dir)
    score = score_run(run, metrics, verdict=verdict or judge(run), force_reference_n=force_reference_n)
    if out_dir is None:
        return ScoredRun(run, score)
    out_dir.mkdir(parents=True, exist_ok=True)
    json_path, csv_path = out_dir / "score.json", out_dir / "score.csv"
    json_path.write_text(score.to_json())
    csv_path.write_text(score.to_csv())
    return ScoredRun(run, score, json_path, csv_path)


def named_by_run_folder(run: RunRecord, out_dir: Path | None) -> RunRecord:
    """An engine record written into ``bags/<scenario>/<start time>`` named ``<scenario>/<start time>``.

    A bag read from a run folder is named so already (``bag.read_bag``); an
    engine record knows only its scenario, and several runs of one scenario
    would share that name in a report.
    """
    if run.backend != "engine" or out_dir is None or run.name.endswith(f"/{out_dir.name}"):
        return run
    return run.with_(name=f"{run.name}/{out_dir.name}")


def judge_bag(bag: Path) -> tuple[RunRecord, Verdict]:
    """Read one bag, with the ``summary.json`` of its run folder when there is one, and judge the run.

    Raises
    ------
    BagError
        The bag cannot be read.
    """
    from cnc_tools.bagio.bag import read_bag  # rosbags: loaded only when a bag is read
    from cnc_tools.bagio.diagnostics import read_statuses

    record = read_bag(bag)
    summary = read_summary(run_folder(bag) / "summary.json")
    if summary is not None:
        record = record.with_(summary=summary)
    namespace, statuses = read_statuses(bag)
    return record, judge(record, statuses, namespace)


def run_folder(bag: Path) -> Path:
    """The run folder a bag (folder or ``.mcap`` file) was recorded into: the bag folder's parent."""
    folder = bag if bag.is_dir() else bag.parent
    return folder.resolve().parent


def score_bag(bag: Path, out_dir: Path | None = None, metrics: Sequence[str] | None = None,
              force_reference_n: float | None = None) -> ScoredRun:
    """Read one bag, judge the run and score it whatever the verdict (see :func:`score_record`)."""
    record, verdict = judge_bag(bag)
    return score_record(record, out_dir, metrics, verdict, force_reference_n)


def report_runs(scored: Sequence[ScoredRun], out_dir: Path) -> list[Path]:
    """The PNG figures of one or more scored runs, side by side."""
    from cnc_tools.analysis.report import write_report  # matplotlib: loaded only when plotting

    return write_report([s.run for s in scored], out_dir, scores=[s.score for s in scored])
