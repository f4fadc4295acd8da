"""The benches of ``cnc-contour bench NAME``, listed explicitly (speed benches and paper reproductions)."""
from __future__ import annotations

import argparse
from collections.abc import Callable

from cnc_contour_control.config import require_choice
from cnc_tools.bench.bag_write import bag_write_bench
from cnc_tools.bench.cross_axis import cross_axis_bench
from cnc_tools.bench.blending import blending_bench
from cnc_tools.bench.compensator import compensator_bench
from cnc_tools.bench.compose import compose_bench
from cnc_tools.bench.engine import engine_bench
from cnc_tools.bench.estimator import estimator_bench
from cnc_tools.bench.graph import graph_bench
from cnc_tools.bench.laws import laws
from cnc_tools.bench.lockstep import lockstep_bench
from cnc_tools.bench.scoring import scoring
from cnc_tools.bench.sweep import sweep_bench
from cnc_tools.bench.tune import tune_bench
from cnc_tools.reproductions.paper000.assumptions import paper000_assumptions_bench
from cnc_tools.reproductions.paper000.bench import paper000_bench, paper000_pid_bench
from cnc_tools.reproductions.paper000.calibration import paper000_calibrated_bench
from cnc_tools.reproductions.paper001.bench import paper001_bench
from cnc_tools.reproductions.paper002.bench import paper002_bench
from cnc_tools.reproductions.paper002.speed import paper002_speed_bench
from cnc_tools.reproductions.paper002.transfer import paper002_transfer_bench
from cnc_tools.reproductions.paper003.bench import paper003_bench
from cnc_tools.reproductions.paper004.bench import paper004_bench
from cnc_tools.reproductions.paper004.milling import paper004_milling_bench
from cnc_tools.reproductions.paper004.speed import paper004_speed_bench

#: A bench: parsed options in, exit code out.
Bench = Callable[[argparse.Namespace], int]

#: Benches by name.
BENCHES: dict[str, Bench] = {
    "lockstep": lockstep_bench,
    "engine": engine_bench,
    "graph": graph_bench,
    "cross-axis": cross_axis_bench,
    "compose": compose_bench,
    "bag-write": bag_write_bench,
    "scoring": scoring,
    "sweep": sweep_bench,
    "tune": tune_bench,
    "blending": blending_bench,
    "laws": laws,
    "compensator": compensator_bench,
    "estimator": estimator_bench,
    "paper000-pid": paper000_pid_bench,
    "paper000": paper000_bench,
    "paper000-assumptions": paper000_assumptions_bench,
    "paper000-calibrated": paper000_calibrated_bench,
    "paper001": paper001_bench,
    "paper002": paper002_bench,
    "paper002-speed": paper002_speed_bench,
    "paper002-transfer": paper002_transfer_bench,
    "paper003": paper003_bench,
    "paper004": paper004_bench,
    "paper004-milling": paper004_milling_bench,
    "paper004-speed": paper004_speed_bench,
}


def get_bench(name: str) -> Bench:
    """The bench called ``name``; an unknown name is a ConfigError listing the valid ones."""
    require_choice("bench", name, BENCHES)
    return BENCHES[name]
