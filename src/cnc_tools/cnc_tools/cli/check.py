"""``cnc-contour check SCENARIO``: validate a scenario as a run would, and print what it resolves to.

What ``check`` accepts the nodes accept: the scenario's run values are held to
the plant node's declared ranges (:mod:`cnc_tools.runs.scenario`), and every
node's parameters are built here exactly as the runner builds them before it
starts a process (:func:`cnc_tools.runs.graph_nodes.graph_nodes`, validated
by the nodes' own config classes). Nothing is started.
"""
from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from cnc_tools.runs.graph_nodes import graph_nodes
from cnc_tools.runs.scenario import load_scenario


def configure(parser: argparse.ArgumentParser) -> None:
    """Options of ``cnc-contour check``."""
    parser.add_argument("scenario", type=Path)


def check(args: argparse.Namespace) -> int:
    """Validate a scenario and print what it resolves to."""
    scenario = load_scenario(args.scenario)
    with tempfile.TemporaryDirectory(prefix="cnc_check_") as folder:
        nodes = graph_nodes(scenario, Path(folder))
    print(json.dumps({"name": scenario.name, "axes": scenario.axes, "sample_time_s": scenario.sample_time_s,
                      "duration_s": scenario.duration_s, "segments": len(scenario.program.segments),
                      "length_mm": scenario.program.total_length_m * 1e3,
                      "nodes": [node.name for node in nodes]}, indent=2))
    return 0
