"""Bench ``blending``, dense CAM: a program of many short segments streamed tick by tick as the node streams it.

The program (:func:`dense_spiral`) is an Archimedean spiral from R 10 mm, 1 mm a turn, in chords of
``F T`` (1300 mm/min, T = 1 ms: one programmed segment per tick), ``--segments`` of them (150 000 by
default: 150 s at the programmed feed; 10 000 with ``--quick``). Its curvature asks at most 47 mm/s² at
that feed, so the limits allow the programmed feed everywhere but the start and the end.

It runs through :class:`~cnc_contour_control.motion.feed_override.LiveReference` (what the interpolator
node calls each tick; override 100 %) with a window of ``WINDOW`` planned segments, so the plan streams
(:mod:`cnc_contour_control.motion.plan_stream`): each tick plans at most one small step ahead and forgets
what is behind the tool. Printed: the CPU time of the ticks (median, p99.9, max; a tick over
``TICK_BUDGET_S`` counts as late: the other stages of a composed 1 kHz loop take about 0.37 ms,
``bench compose``), the feed over the programmed feed from 2 mm after the start to 2 mm before the end
(goal >= 0.9), and the plan's held entries (:meth:`StreamPlan.held_rows`) after the first tick, at their
largest and at the end (goal: the largest within twice the first).
"""
from __future__ import annotations

import argparse
import math
import os
import time
from dataclasses import replace
from typing import Any

import numpy as np

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig
from cnc_contour_control.motion.geometry import Program
from cnc_tools.analysis.tables import format_table, goal_text
from cnc_tools.bench.blending import bench_config, limits_for
from cnc_tools.bench.blending_corpus import FEED_M_S, polyline

SEGMENTS = 150_000
QUICK_SEGMENTS = 10_000
TICK_S = 1e-3
#: The planned segments the stream looks ahead (braking from the feed takes about 45 of these chords).
WINDOW = 200
#: A tick whose reference took more CPU than this is late (1 ms less the composed loop's other stages).
TICK_BUDGET_S = 0.5e-3
FEED_GOAL = 0.9
#: Distance from the start and from the end left out of the feed ratio (the ramps), m.
RAMP_M = 0.002


def add_options(parser: argparse.ArgumentParser) -> None:
    """``--segments`` (bench blending)."""
    parser.add_argument("--segments", type=int, help=f"bench blending: segments of the dense-CAM program "
                        f"(default {SEGMENTS}, {QUICK_SEGMENTS} with --quick)")


def dense_spiral(segments: int, chord_m: float = FEED_M_S * TICK_S, start_radius_m: float = 0.01,
                 pitch_m: float = 0.001) -> Program:
    """An Archimedean spiral in ``segments`` chords of about ``chord_m`` from ``start_radius_m`` outward."""
    theta = np.zeros(segments + 1)
    for k in range(segments):  # the chord of a step dθ at radius r is about r dθ
        theta[k + 1] = theta[k] + chord_m / (start_radius_m + pitch_m * theta[k] / (2.0 * math.pi))
    radius = start_radius_m + pitch_m * theta / (2.0 * math.pi)
    program = polyline("dense-spiral", np.c_[radius * np.cos(theta), radius * np.sin(theta)])
    return Program(f"dense-spiral-{segments}", program.axis_names, program.segments)


def stream_run(program: Program) -> dict[str, Any]:
    """Step ``program`` at 1 ms ticks of the wall clock with a streaming window; per-tick latency, feed, memory."""
    config = OverrideConfig(schedule_times_s=(0.0,), schedule_ratios=(1.0,))
    started = time.process_time()
    live = LiveReference(program, limits_for(program), replace(bench_config(), look_ahead_segments=WINDOW), config)
    if live.planner is None:
        raise ConfigError(f"{program.name}: {len(program.segments)} segments do not stream with a window of {WINDOW}")
    construct_s = time.process_time() - started
    stream = live.planner.stream
    tick_s, feed, path, held = [], [], [], [stream.held_rows()]
    clock, tick, next_s = time.perf_counter, 0, time.perf_counter()
    while True:
        next_s += TICK_S
        before = clock()
        sample = live.step(round(tick * TICK_S * 1e9), 1.0)
        tick_s.append(clock() - before)
        feed.append(sample.feed_m_s / sample.programmed_feed_m_s)
        path.append(sample.path_length_m)
        if tick % 1000 == 0:
            held.append(stream.held_rows())
        if sample.done:
            break
        tick += 1
        time.sleep(max(next_s - clock(), 0.0))
    held.append(stream.held_rows())
    figures = _figures(program, construct_s, np.array(tick_s), np.array(feed), np.array(path), held,
                       stream.total_length_m)
    return {**figures, "planner_waits": live.planner.waits, "load_1min": os.getloadavg()[0]}


def _figures(program: Program, construct_s: float, tick_s: np.ndarray, feed: np.ndarray, path_m: np.ndarray,
             held: list[int], total_m: float) -> dict[str, Any]:
    middle = (path_m > RAMP_M) & (path_m < total_m - RAMP_M)
    half = len(held) // 2
    return {"program": program.name, "segments": len(program.segments), "window": WINDOW, "ticks": len(tick_s),
            "plan_cpu_s": construct_s, "tick_p50_s": float(np.median(tick_s)),
            "tick_p999_s": float(np.quantile(tick_s, 0.999)), "tick_max_s": float(tick_s.max()),
            "late_ticks": int(np.count_nonzero(tick_s > TICK_BUDGET_S)),
            "feed_ratio_min": float(feed[middle].min()),
            "feed_ratio_share_ok": float(np.mean(feed[middle] >= FEED_GOAL)),
            "held_start": held[0], "held_max_first_half": max(held[:half + 1]),
            "held_max_second_half": max(held[half:]), "held_end": held[-1]}


def dense_cam(options: argparse.Namespace) -> dict[str, Any]:
    """Print and return the dense-CAM stream's figures."""
    segments = getattr(options, "segments", None) or (QUICK_SEGMENTS if options.quick else SEGMENTS)
    f = stream_run(dense_spiral(segments))
    print(f"dense CAM: {f['segments']} segments of {FEED_M_S * TICK_S * 1e6:.1f} um at 1300 mm/min, T = 1 ms on "
          f"the wall clock, window {WINDOW}, planned in a thread ahead of the tool (first chunk "
          f"{f['plan_cpu_s']:.3f} s CPU); load {f['load_1min']:.1f}")
    print(format_table(
        ["ticks", "tick p50 us", "p99.9 us", "max us", f"> {TICK_BUDGET_S * 1e3:g} ms", "waited for plan",
         "feed/programmed min", "held start", "held max 1st half", "2nd half", "end", "0 waits", "feed >= 90 %",
         "memory flat"],
        [[f["ticks"], round(f["tick_p50_s"] * 1e6, 1), round(f["tick_p999_s"] * 1e6, 1),
          round(f["tick_max_s"] * 1e6, 1), f["late_ticks"], f["planner_waits"], round(f["feed_ratio_min"], 4),
          f["held_start"], f["held_max_first_half"], f["held_max_second_half"], f["held_end"],
          goal_text(f["planner_waits"] == 0), goal_text(f["feed_ratio_min"] >= FEED_GOAL),
          goal_text(f["held_max_second_half"] <= f["held_max_first_half"])]]))
    return f
