"""``cnc-contour bench live``: the lag from a tick to a viewer at T = 1 ms, and whether the peaks survive.

paper 000's circle at T = 1 ms on the engine with ``--live`` (paced in real time), watched by the protocol
client (:func:`cnc_tools.live.watch.watch_engine_run`) from before the first tick, twice: subscribed to the
channels the shipped layout shows (what a viewer watches; the goal is judged there), then to every channel
(the worst case: every full-rate stream at once, each CDR message made). The lag of a message is its arrival
at the client minus its log time (the wall time its tick reached the feed); the goal is <= 100 ms. The exact
contour error's peak stream must hold the run's peak as the scorer computes it from the bag, exactly. The
1-minute load is printed before and after (the lag is the machine's as much as the code's).
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from cnc_tools.analysis.scoring import contour_error_series
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.bagio.bag import read_bag
from cnc_tools.live.layout import LAYOUT_PATH, layout_topics
from cnc_tools.live.watch import Watched, watch_engine_run
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.scenario import Scenario, load_scenario

SCENARIO = "scenarios/paper000_circle_high.yaml"
SAMPLE_TIME_S = 0.001
#: The goal: a tick reaches a viewer within this, ms.
LAG_GOAL_MS = 100.0
#: Channels whose lag is reported (the per-tick CDR one, the batched exact error, a peak stream).
REPORTED = ("/cnc/joint_states", "/cnc/servo/x/command", "/live/contour_error/exact",
            "/live/contour_error/exact/peaks", "/live/servo/x/peaks", "/live/xy")


def _lags_ms(watched: Watched, topic: str) -> list[float]:
    return [(r.arrived_ns - r.log_time_ns) * 1e-6 for r in watched.of(topic)]


def _peaks(watched: Watched) -> tuple[float, float]:
    """(the peak of the exact peak stream, the scorer's peak from the bag), µm."""
    series, _ = contour_error_series(read_bag(watched.record.source / "bag"))
    streamed = max(abs(r.json()["contour_error_um"]) for r in watched.of("/live/contour_error/exact/peaks"))
    return streamed, float(np.abs(series.error_m * 1e6).max())


def _watch(scenario: Scenario, run_dir: Path, subscribed: str) -> tuple[Watched, list[tuple[Any, ...]], float]:
    """One watched run: the lag rows of the channels the viewer subscribed to, and the worst lag [ms]."""
    chosen = () if subscribed == "every channel" else tuple(sorted(layout_topics(json.loads(
        LAYOUT_PATH.read_text(encoding="utf-8")))))
    watched = watch_engine_run(scenario, run_dir, chosen)
    rows, worst_ms = [], 0.0
    for topic in (t for t in REPORTED if watched.of(t)):
        lags = _lags_ms(watched, topic)
        worst_ms = max(worst_ms, max(lags))
        rows.append((subscribed, topic, len(lags), round(float(np.median(lags)), 2),
                     round(float(np.percentile(lags, 99)), 2), round(max(lags), 2)))
    return watched, rows, worst_ms


def live_bench(args: argparse.Namespace) -> int:
    """Run twice (the layout's channels, then every channel), print the lag table, the peak check and the load;
    0 when both goals are met for the layout's channels."""
    overrides: dict[str, Any] = {"sample_time_s": SAMPLE_TIME_S}
    if args.quick:
        overrides["duration_s"] = 2.0
    scenario = load_scenario(project_root() / SCENARIO, overrides)
    out = args.out or project_root() / "bags" / "bench" / "live" / timestamp()
    load_before = os.getloadavg()[0]
    print(f"bench live: {scenario.name} at T = {SAMPLE_TIME_S * 1e3:g} ms, {scenario.duration_s:.2f} s in real "
          f"time, watched on the layout's channels, then on every channel (load {load_before:.2f})", flush=True)
    watched, rows, worst_ms = _watch(scenario, out / "layout", "layout")
    _, every, every_worst_ms = _watch(scenario, out / "every", "every channel")
    load_after = os.getloadavg()[0]
    print(format_table(("subscribed", "channel", "messages", "lag median [ms]", "p99 [ms]", "max [ms]"),
                       rows + every))
    streamed, scored = _peaks(watched)
    kept = streamed == scored
    met = worst_ms <= LAG_GOAL_MS
    print(f"  lag max {worst_ms:.1f} ms on the layout's channels (goal <= {LAG_GOAL_MS:g} ms: "
          f"{'met' if met else 'NOT met'}), {every_worst_ms:.1f} ms on every channel"
          f"\n  contour-error peak: peak stream {streamed:.6f} um, scorer (bag) {scored:.6f} um: "
          f"{'kept exactly' if kept else 'NOT kept'}\n  load (1 min) {load_before:.2f} before, {load_after:.2f} "
          f"after; {os.cpu_count()} cores")
    write_json(args.json, {"lag_ms": {f"{r[0]} {r[1]}": {"median": r[3], "p99": r[4], "max": r[5]}
                                      for r in rows + every},
                           "peak_um": {"streamed": streamed, "scored": scored, "kept": kept},
                           "load": [load_before, load_after], "machine": machine()})
    return 0 if kept and met else 1
