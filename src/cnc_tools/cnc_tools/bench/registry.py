"""The benches of ``cnc-contour bench NAME``, listed explicitly (speed benches and paper reproductions).

A bench's module is imported when the bench is looked up, not when the
registry is: ``cnc-contour bench lockstep`` does not import toppra, the
tuning objectives or the paper reproductions.
"""
from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable, Iterator, Mapping

from cnc_contour_control.core.config import require_choice

#: A bench: parsed options in, exit code out.
Bench = Callable[[argparse.Namespace], int]

#: Benches by name: "module:function".
TARGETS: dict[str, str] = {
    "lockstep": "cnc_tools.bench.lockstep:lockstep_bench",
    "hops": "cnc_tools.bench.hops:hops_bench",
    "engine": "cnc_tools.bench.engine:engine_bench",
    "graph": "cnc_tools.bench.graph:graph_bench",
    "cross-axis": "cnc_tools.bench.cross_axis:cross_axis_bench",
    "compose": "cnc_tools.bench.compose:compose_bench",
    "bag-write": "cnc_tools.bench.bag_write:bag_write_bench",
    "fuzz": "cnc_tools.bench.fuzz:fuzz_bench",
    "scoring": "cnc_tools.bench.scoring:scoring",
    "sweep": "cnc_tools.bench.sweep:sweep_bench",
    "tune": "cnc_tools.bench.tune:tune_bench",
    "best": "cnc_tools.bench.best:best_bench",
    "blending": "cnc_tools.bench.blending:blending_bench",
    "jerk": "cnc_tools.bench.jerk:jerk_bench",
    "laws": "cnc_tools.bench.laws:laws",
    "compensator": "cnc_tools.bench.compensator:compensator_bench",
    "estimator": "cnc_tools.bench.estimator:estimator_bench",
    "live": "cnc_tools.bench.live:live_bench",
    "paper000-pid": "cnc_tools.reproductions.paper000.bench:paper000_pid_bench",
    "paper000": "cnc_tools.reproductions.paper000.bench:paper000_bench",
    "paper000-assumptions": "cnc_tools.reproductions.paper000.assumptions:paper000_assumptions_bench",
    "paper000-calibrated": "cnc_tools.reproductions.paper000.calibration:paper000_calibrated_bench",
    "paper001": "cnc_tools.reproductions.paper001.bench:paper001_bench",
    "paper002": "cnc_tools.reproductions.paper002.bench:paper002_bench",
    "paper002-speed": "cnc_tools.reproductions.paper002.speed:paper002_speed_bench",
    "paper002-transfer": "cnc_tools.reproductions.paper002.transfer:paper002_transfer_bench",
    "paper003": "cnc_tools.reproductions.paper003.bench:paper003_bench",
    "paper004": "cnc_tools.reproductions.paper004.bench:paper004_bench",
    "paper004-milling": "cnc_tools.reproductions.paper004.milling:paper004_milling_bench",
    "paper004-speed": "cnc_tools.reproductions.paper004.speed:paper004_speed_bench",
}


class _Benches(Mapping[str, Bench]):
    """:data:`TARGETS` as a mapping of name -> bench function, each imported on first lookup."""

    def __getitem__(self, name: str) -> Bench:
        module, _, function = TARGETS[name].partition(":")
        return getattr(importlib.import_module(module), function)

    def __iter__(self) -> Iterator[str]:
        return iter(TARGETS)

    def __len__(self) -> int:
        return len(TARGETS)


#: Benches by name.
BENCHES: Mapping[str, Bench] = _Benches()


def get_bench(name: str) -> Bench:
    """The bench called ``name``; an unknown name is a ConfigError listing the valid ones."""
    require_choice("bench", name, TARGETS)
    return BENCHES[name]
