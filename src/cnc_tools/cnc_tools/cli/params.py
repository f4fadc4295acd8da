"""``cnc-contour params SCENARIO --out DIR``: the graph's parameter files, for ``ros2 launch`` or ``ros2 run``.

Writes what ``cnc-contour run`` starts its nodes with (one ROS 2 parameters
file per node, the program, ``graph.yaml`` naming each node's package and
executable), in the configs' own units, for::

    ros2 launch cnc_contour_bringup contour_graph.launch.py params_dir:=DIR
"""
from __future__ import annotations

import argparse
from pathlib import Path

from cnc_contour_control.core.errors import CncError
from cnc_tools.cli.common import parse_overrides
from cnc_tools.runs.graph_nodes import NAMESPACE, graph_nodes, write_params_dir
from cnc_tools.runs.scenario import load_scenario


def configure(parser: argparse.ArgumentParser) -> None:
    """Options of ``cnc-contour params``."""
    parser.add_argument("scenario", type=Path, help="scenario YAML file")
    parser.add_argument("--out", type=Path, required=True, help="folder to write (must not hold a graph yet)")
    parser.add_argument("--extra-subscribers", type=int, default=0, metavar="N",
                        help="readers besides the graph's own that every stage waits for (a bag recorder: 1)")
    parser.add_argument("--input-timeout-s", type=float, default=5.0, metavar="S",
                        help="wall time a tick may wait for its inputs before it is a fault")
    parser.add_argument("--namespace", default=NAMESPACE, help=f"the nodes' namespace (default {NAMESPACE})")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario key, e.g. --set sample_time_s=0.001")


def params(args: argparse.Namespace) -> int:
    """Write the parameter folder of a scenario's graph."""
    if args.extra_subscribers < 0:
        raise CncError(f"--extra-subscribers must be >= 0, got {args.extra_subscribers}")
    out = args.out.resolve()  # the files name each other (program, summary) by absolute path
    if (out / "graph.yaml").exists():
        raise CncError(f"{out} already holds a graph (graph.yaml); choose another folder")
    scenario = load_scenario(args.scenario, parse_overrides(args.overrides))
    nodes = graph_nodes(scenario, out, args.extra_subscribers, args.input_timeout_s)
    write_params_dir(nodes, out, args.namespace)
    print(f"{out}: {', '.join(spec.name for spec in nodes)}")
    print(f"ros2 launch cnc_contour_bringup contour_graph.launch.py params_dir:={out}")
    return 0
