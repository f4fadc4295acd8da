"""``cnc-contour score BAG...`` and ``cnc-contour report BAG...``: score recorded runs, plot them.

``score`` judges each run first (:func:`cnc_tools.runs.outputs.judge_bag`): a
partial or faulted run is reported in one line and scored only with
``--allow-partial``; the exit code is 1 when a run was refused.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cnc_tools.runs.folders import timestamp
from cnc_tools.runs.outputs import judge_bag, report_runs, score_bag, score_record


def configure_score(parser: argparse.ArgumentParser) -> None:
    """Options of ``cnc-contour score``."""
    parser.add_argument("bags", nargs="+", type=Path, help="bag folders (or .mcap files)")
    parser.add_argument("--metrics", nargs="*", help="metric names (default: all registered)")
    parser.add_argument("--out", type=Path, help="write score.json and score.csv per bag under this folder")
    parser.add_argument("--allow-partial", action="store_true",
                        help="also score runs that did not finish, faulted, or whose bag is damaged (reported as such)")


def score(args: argparse.Namespace) -> int:
    """Score recorded runs: exact contour error from the recorded path and positions."""
    status = 0
    used: set[str] = set()
    for bag in args.bags:
        record, verdict = judge_bag(bag)
        if not verdict.complete and not args.allow_partial:
            print(f"cnc-contour score: error: {bag}: run {verdict.describe()} "
                  "(not scored; --allow-partial scores it anyway)", file=sys.stderr)
            status = 1
            continue
        out = args.out / score_folder_name(record.name, used) if args.out else None
        scored = score_record(record, out, args.metrics, verdict)
        print(scored.score.to_table())
        if scored.json_path:
            print(f"json: {scored.json_path}\ncsv:  {scored.csv_path}")
    return status


def score_folder_name(run_name: str, used: set[str]) -> str:
    """The run's folder under ``--out``: its name (scenario and start time, ``/`` as ``_``), ``-2``, ``-3``... when
    an earlier bag of this call took it; noted in ``used``."""
    base = "".join(c if c.isalnum() or c in "-_." else "_" for c in run_name.replace("/", "_")).strip(".") or "run"
    name, k = base, 1
    while name in used:
        k += 1
        name = f"{base}-{k}"
    used.add(name)
    return name


def configure_report(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bags", nargs="+", type=Path, help="bag folders; several are drawn side by side")
    parser.add_argument("--out", type=Path, default=Path("reports") / timestamp(), help="folder for the PNGs")


def report(args: argparse.Namespace) -> int:
    """PNG plots of one or more recorded runs."""
    scored = [score_bag(bag) for bag in args.bags]
    for path in report_runs(scored, args.out):
        print(path)
    return 0
