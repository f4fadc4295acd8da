"""``cnc-contour score BAG...`` and ``cnc-contour report BAG...``: score recorded runs, plot them."""
from __future__ import annotations

import argparse
from pathlib import Path

from cnc_tools.runs.folders import timestamp
from cnc_tools.runs.outputs import report_runs, score_bag


def configure_score(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bags", nargs="+", type=Path, help="bag folders (or .mcap files)")
    parser.add_argument("--metrics", nargs="*", help="metric names (default: all registered)")
    parser.add_argument("--out", type=Path, help="write score.json and score.csv per bag under this folder")


def score(args: argparse.Namespace) -> int:
    """Score recorded runs: exact contour error from the recorded path and positions."""
    status = 0
    for bag in args.bags:
        out = args.out / bag.resolve().parent.name if args.out else None
        scored = score_bag(bag, out, args.metrics)
        print(scored.score.to_table())
        if not scored.run.integrity.complete:
            status = 1
        if scored.json_path:
            print(f"json: {scored.json_path}\ncsv:  {scored.csv_path}")
    return status


def configure_report(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bags", nargs="+", type=Path, help="bag folders; several are drawn side by side")
    parser.add_argument("--out", type=Path, default=Path("reports") / timestamp(), help="folder for the PNGs")


def report(args: argparse.Namespace) -> int:
    """PNG plots of one or more recorded runs."""
    scored = [score_bag(bag) for bag in args.bags]
    for path in report_runs(scored, args.out):
        print(path)
    return 0
