"""``cnc-contour bench live``: the lag from a tick to a viewer at T = 1 ms, and whether the peaks survive.

paper 000's circle at T = 1 ms on the engine with ``--live`` (paced in real time), watched by the protocol
client (:func:`cnc_tools.live.watch.watch_engine_run`) subscribed to every channel from before the first tick
(the worst case: every full-rate stream at once). The lag of a message is its arrival at the client minus its
log time (the wall time its tick reached the feed); the goal is <= 100 ms. The exact contour error's peak stream
must hold the run's peak as the scorer computes it from the bag, exactly. The 1-minute load is printed before
and after (the lag is the machine's as much as the code's).
"""
from __future__ import annotations

import argparse
import os
from typing import Any

import numpy as np

from cnc_tools.analysis.scoring import contour_error_series
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.bagio.bag import read_bag
from cnc_tools.live.watch import Watched, watch_engine_run
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.scenario import load_scenario

SCENARIO = "scenarios/paper000_circle_high.yaml"
SAMPLE_TIME_S = 0.001
#: The goal: a tick reaches a viewer within this, ms.
LAG_GOAL_MS = 100.0
#: Channels whose lag is reported (the per-tick CDR one, the batched exact error, a peak stream).
REPORTED = ("/cnc/joint_states", "/cnc/servo/x/command", "/live/contour_error/exact",
            "/live/contour_error/exact/peaks", "/live/xy")


def _lags_ms(watched: Watched, topic: str) -> list[float]:
    return [(r.arrived_ns - r.log_time_ns) * 1e-6 for r in watched.of(topic)]


def _peaks(watched: Watched) -> tuple[float, float]:
    """(the peak of the exact peak stream, the scorer's peak from the bag), µm."""
    series, _ = contour_error_series(read_bag(watched.record.source / "bag"))
    streamed = max(abs(r.json()["contour_error_um"]) for r in watched.of("/live/contour_error/exact/peaks"))
    return streamed, float(np.abs(series.error_m * 1e6).max())


def live_bench(args: argparse.Namespace) -> int:
    """Run, watch, print the lag table, the peak check and the load; 0 when both goals are met."""
    overrides: dict[str, Any] = {"sample_time_s": SAMPLE_TIME_S}
    if args.quick:
        overrides["duration_s"] = 2.0
    scenario = load_scenario(project_root() / SCENARIO, overrides)
    run_dir = (args.out or project_root() / "bags" / "bench" / "live" / timestamp()) / "run"
    load_before = os.getloadavg()[0]
    print(f"bench live: {scenario.name} at T = {SAMPLE_TIME_S * 1e3:g} ms, {scenario.duration_s:.2f} s in real "
          f"time, watched on every channel (load {load_before:.2f})", flush=True)
    watched = watch_engine_run(scenario, run_dir, ())
    load_after = os.getloadavg()[0]
    rows, worst_ms = [], 0.0
    for topic in REPORTED:
        lags = _lags_ms(watched, topic)
        worst_ms = max(worst_ms, max(lags))
        rows.append((topic, len(lags), round(float(np.median(lags)), 2), round(float(np.percentile(lags, 99)), 2),
                     round(max(lags), 2)))
    print(format_table(("channel", "messages", "lag median [ms]", "p99 [ms]", "max [ms]"), rows))
    streamed, scored = _peaks(watched)
    kept = streamed == scored
    print(f"  lag max {worst_ms:.1f} ms (goal <= {LAG_GOAL_MS:g} ms: {'met' if worst_ms <= LAG_GOAL_MS else 'NOT met'})"
          f"\n  contour-error peak: peak stream {streamed:.6f} um, scorer (bag) {scored:.6f} um: "
          f"{'kept exactly' if kept else 'NOT kept'}\n  load (1 min) {load_before:.2f} before, {load_after:.2f} after; "
          f"{os.cpu_count()} cores")
    write_json(args.json, {"lag_ms": {row[0]: {"median": row[2], "p99": row[3], "max": row[4]} for row in rows},
                           "peak_um": {"streamed": streamed, "scored": scored, "kept": kept},
                           "load": [load_before, load_after], "machine": machine()})
    return 0 if kept and worst_ms <= LAG_GOAL_MS else 1
