"""A recorded run's path to people: read the bag, score it, write JSON/CSV and the plots."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from cnc_tools.bagio.bag import RecordedRun, read_bag
from cnc_tools.analysis.scoring import Score, score_run


@dataclass(frozen=True)
class ScoredRun:
    """A run read from its bag, its score, and the files written for it."""

    run: RecordedRun
    score: Score
    json_path: Path | None = None
    csv_path: Path | None = None


def score_bag(bag: Path, out_dir: Path | None = None, metrics: Sequence[str] | None = None) -> ScoredRun:
    """Score one bag; with ``out_dir``, also write ``score.json`` and ``score.csv`` there."""
    run = read_bag(bag)
    score = score_run(run, metrics)
    if out_dir is None:
        return ScoredRun(run, score)
    out_dir.mkdir(parents=True, exist_ok=True)
    json_path, csv_path = out_dir / "score.json", out_dir / "score.csv"
    json_path.write_text(score.to_json())
    csv_path.write_text(score.to_csv())
    return ScoredRun(run, score, json_path, csv_path)


def report_runs(scored: Sequence[ScoredRun], out_dir: Path) -> list[Path]:
    """The PNG figures of one or more scored runs, side by side."""
    from cnc_tools.analysis.report import write_report  # matplotlib: loaded only when plotting

    return write_report([s.run for s in scored], out_dir, scores=[s.score for s in scored])
