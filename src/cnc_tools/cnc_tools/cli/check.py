"""``cnc-contour check SCENARIO``: validate a scenario and print what it resolves to."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from cnc_tools.runs.scenario import load_scenario


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=Path)


def check(args: argparse.Namespace) -> int:
    """Validate a scenario and print what it resolves to."""
    scenario = load_scenario(args.scenario)
    print(json.dumps({"name": scenario.name, "axes": scenario.axes, "sample_time_s": scenario.sample_time_s,
                      "duration_s": scenario.duration_s, "segments": len(scenario.program.segments),
                      "length_mm": scenario.program.total_length_m * 1e3}, indent=2))
    return 0
