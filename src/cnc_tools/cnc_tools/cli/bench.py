"""The ``cnc-contour bench NAME [--quick] [--json PATH] [--out DIR] [--engine] [--seeds N] [--against REV] [--record]
[--rounds N] [--dds-profile NAME=PATH]`` subcommand."""
from __future__ import annotations

import argparse
from pathlib import Path

from cnc_tools.bench.registry import TARGETS, get_bench
from cnc_tools.runs.progress import task as progress_task


def configure(parser: argparse.ArgumentParser) -> None:
    """The options every bench shares, plus ``--against`` (engine and graph benches) and ``--record`` (graph bench)."""
    from cnc_tools.bench.blending_stream import add_options as add_blending_options
    from cnc_tools.bench.engine import add_options as add_engine_options  # the bench command only
    from cnc_tools.bench.fuzz import add_options as add_fuzz_options
    from cnc_tools.bench.graph import add_options as add_graph_options
    from cnc_tools.bench.hops import add_options as add_hops_options

    parser.add_argument("name", help=f"benchmark, one of {sorted(TARGETS)}")
    parser.add_argument("--quick", action="store_true", help="shorter runs and fewer repetitions (< 30 s)")
    parser.add_argument("--json", type=Path, help="also write the measured figures to this JSON file")
    parser.add_argument("--out", type=Path, help="folder for run files (default bags/bench/<name>/<timestamp>)")
    parser.add_argument("--engine", action="store_true",
                        help="run in-process instead of the node graph (paper benches)")
    parser.add_argument("--seeds", type=int, help="plant seeds 1..N per row (paper benches)")
    parser.add_argument("--workers", type=int, help="local processes for a bench's independent runs "
                        "(paper003, best; default all cores)")
    parser.add_argument("--scheduler",
                        help="Dask scheduler tcp://host:port for a bench's independent runs (paper003, best)")
    add_engine_options(parser)
    add_graph_options(parser)
    add_hops_options(parser)
    add_fuzz_options(parser)
    add_blending_options(parser)


def bench(args: argparse.Namespace) -> int:
    """Run one benchmark and print its table; its progress (the runs of its sweeps) on stderr."""
    chosen = get_bench(args.name)
    with progress_task(f"bench {args.name}"):
        return chosen(args)
