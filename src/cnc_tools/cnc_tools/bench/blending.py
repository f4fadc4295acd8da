"""Bench ``blending``: corner blending within a path tolerance on a corpus of CAM-like programs.

Per program of :mod:`cnc_tools.bench.blending_corpus`, at ``path_tolerance_mm``
0.01, paper 000's limits (2000 mm/min, 250 mm/s² per axis), a machine tool's jerk limit
(``MAX_JERK_M_S3``: the acceleration limit reached in 25 ms; measured, not given to the planner: the
jerk-limited mode, :mod:`cnc_tools.bench.jerk`) and the bench's planner options
(``BEST_OPTIONS`` in :mod:`~cnc_tools.bench.blending_limits`, the shipped defaults):

- worst velocity, acceleration and jerk ratio per axis on the sampled reference, each the larger of the
  analytic value and the finite difference (:func:`sampled_ratios`; goal <= 1 + 1e-9);
- worst deviation of the reference from the programmed path over the tolerance P, measured exactly
  to the programmed segments each sample's planned segment comes from
  (``BlendedProgram.local_deviation_m``, an upper bound of the contour distance; goal <= 1);
- cycle time over the exact-stop (G61: tolerance 0, same limits) time (goal <= 1 on every program) and
  over the time-optimal (v, a) bound on the same blended path (``toppra``, :mod:`cnc_tools.bench.time_optimal`;
  goal <= ``TOPPRA_GOAL`` on the circles, the pocket and the raster: toppra has no jerk limit);
- the override sweep (:mod:`cnc_tools.bench.blending_override`) and the dense-CAM stream
  (:mod:`cnc_tools.bench.blending_stream`);
- planning time per segment against program length (polygons of 0.2 mm sides; CPU time, beside the
  1-minute load average), whole and streaming (a window of ``STREAM_WINDOW`` segments,
  :mod:`cnc_contour_control.motion.plan_stream`): CPU time to the first sample beside the whole plan's.
"""
from __future__ import annotations

import argparse
import dataclasses
import gc
import os
import time
from typing import Any

import numpy as np

from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.bench.blending_corpus import CORPUS, polygon, true_circle
from cnc_tools.bench.blending_limits import (
    LIMIT_GOAL,
    MAX_ACCELERATION_M_S2,
    MAX_JERK_M_S3,
    MAX_VELOCITY_M_S,
    TOLERANCE_MM,
    bench_config,
    limits_for,
    reference_ratios,
    worst_deviation_m,
)

#: Cycle time over toppra's (v, a) bound, on :data:`TOPPRA_PROGRAMS`.
TOPPRA_GOAL = 1.15
TOPPRA_PROGRAMS = ("circle-36-gon", "circle-360-gon", "circle-3600-gon", "pocket", "raster-3axis")
#: The streaming planner's window in the planning-cost table, planned segments.
STREAM_WINDOW = 200
PLAN_SIZES = (1_000, 10_000, 200_000)


def program_figures(program: Program, spacing_m: float) -> dict[str, Any]:
    """The bench's figures for one program."""
    from cnc_tools.bench.time_optimal import time_optimal_s  # toppra: only when the corpus table runs

    # The blending planner without a jerk limit, so toppra's (v, a) bound is taken on the same blended path; its
    # jerk is measured against MAX_JERK_M_S3 all the same. The jerk-limited mode's corners are not in
    # Interpolator.program (toppra would see the sharp corners), so it has its own bench: `bench jerk`.
    limits = limits_for(program)
    started = time.perf_counter()
    interpolator = Interpolator(program, limits, bench_config())
    plan_s = time.perf_counter() - started
    ratios = reference_ratios(interpolator)
    optimal_s = time_optimal_s(interpolator.program, limits, spacing_m)
    exact_stop = Interpolator(program, limits, bench_config(0.0))
    return {"program": program.name, "segments": len(program.segments), "blends": len(interpolator.blended.blends),
            "cycle_s": interpolator.duration_s, "exact_stop_s": exact_stop.duration_s,
            "toppra_s": optimal_s, "plan_s": plan_s, **{name: value.tolist() for name, value in ratios.items()},
            "deviation_over_p": worst_deviation_m(interpolator) / (TOLERANCE_MM * 1e-3)}


def goals(f: dict[str, Any]) -> dict[str, bool | None]:
    """Each goal met or not for one program's figures (None: no such goal for it)."""
    return {"deviation": f["deviation_over_p"] <= LIMIT_GOAL,
            "v, a": max(f["velocity_ratio"] + f["acceleration_ratio"]) <= LIMIT_GOAL,
            "jerk": max(f["jerk_ratio"]) <= LIMIT_GOAL,
            "<= G61": f["cycle_s"] <= f["exact_stop_s"],
            "toppra": f["cycle_s"] <= TOPPRA_GOAL * f["toppra_s"] if f["program"] in TOPPRA_PROGRAMS else None}


def _per_axis(values: list[float]) -> str:
    return " ".join(f"{v:.4f}" for v in values)


def _row(f: dict[str, Any]) -> list[object]:
    met = [goal_text(m) if m is not None else "-" for m in goals(f).values()]
    return [f["program"], f["segments"], f["blends"], f"{f['exact_stop_s']:.3f}", f"{f['cycle_s']:.3f}",
            f"{f['toppra_s']:.3f}", f"{f['cycle_s'] / f['toppra_s']:.4f}", f"{f['cycle_s'] / f['exact_stop_s']:.4f}",
            f"{f['deviation_over_p']:.4f}", _per_axis(f["velocity_ratio"]), _per_axis(f["acceleration_ratio"]),
            _per_axis(f["jerk_ratio"]), *met]


def planning_cost(sizes: tuple[int, ...], windows: tuple[int | None, ...] = (None,)) -> list[dict[str, float]]:
    """Plan time per programmed segment for polygons of 0.2 mm sides with ``sizes`` sides, per look-ahead window.

    Per size and window (None: the default window, the whole program planned at construction; a window shorter
    than the program streams, :mod:`cnc_contour_control.motion.plan_stream`): CPU time to the first sample (construction
    and ``sample(0)``), CPU and wall time to the whole plan (streaming: planned to the end by ``duration_s``).
    """
    rows = []
    for sides in sizes:
        program = polygon(sides, radius_m=sides * 2e-4 / (2 * np.pi))
        for window in windows:
            config = bench_config() if window is None else dataclasses.replace(bench_config(),
                                                                               look_ahead_segments=window)
            gc.collect()  # the previous plan's objects are not this one's cost
            started, started_cpu = time.perf_counter(), time.process_time()
            interpolator = Interpolator(program, limits_for(program), config)
            interpolator.sample(0.0)
            first_cpu = time.process_time() - started_cpu
            _ = interpolator.duration_s  # streaming: plans to the end
            elapsed, cpu = time.perf_counter() - started, time.process_time() - started_cpu
            del interpolator
            rows.append({"segments": sides, "window": window or config.look_ahead_segments,
                         "streaming": window is not None, "first_sample_cpu_s": first_cpu, "plan_s": elapsed,
                         "plan_cpu_s": cpu, "us_per_segment": cpu / sides * 1e6, "load_1min": os.getloadavg()[0]})
    return rows


def corpus_table(quick: bool) -> tuple[float, list[dict[str, Any]]]:
    """Print the per-program table; the true arc's time (s) and the figures."""
    spacing_m = 2e-4 if quick else 5e-5
    arc_s = Interpolator(true_circle(), limits_for(true_circle()), bench_config(0.0)).duration_s
    figures = [program_figures(make(), spacing_m) for make, in_quick in CORPUS.values() if in_quick or not quick]
    config = bench_config()
    print(f"blending at P = {TOLERANCE_MM} mm, {MAX_VELOCITY_M_S * 60000:.0f} mm/min, "
          f"{MAX_ACCELERATION_M_S2 * 1e3:.0f} mm/s^2 per axis, jerk measured against {MAX_JERK_M_S3 * 1e3:.0f} mm/s^3 "
          f"(not given to the planner: the jerk-limited mode is `bench jerk`); planner options (arcs: "
          f"combined budget {config.arc_combined_budget}, centripetal fraction {config.arc_centripetal_fraction}, "
          f"{config.arc_speed_bands} speed bands); true arc R 20 mm: {arc_s:.3f} s; toppra grid {spacing_m * 1e3:g} mm")
    print(format_table(["program", "segs", "blends", "G61 s", "cycle s", "toppra s", "/toppra", "/G61", "dev/P",
                        "v ratio per axis", "a ratio per axis", "jerk ratio per axis", "dev<=P", "v,a<=1",
                        "jerk<=1", "<=G61", f"<={TOPPRA_GOAL} toppra"],
                       [_row(f) for f in figures]))
    return arc_s, figures


def planning_table(quick: bool) -> list[dict[str, float]]:
    """Print and return the planning cost, whole and streaming."""
    cost = planning_cost(PLAN_SIZES[:2] if quick else PLAN_SIZES, (None, STREAM_WINDOW))
    print(format_table(["segments", "plan", "first sample CPU s", "plan wall s", "plan CPU s", "CPU us/segment",
                        "load (1 min)"],
                       [[c["segments"], f"stream W={c['window']}" if c["streaming"] else "whole",
                         round(c["first_sample_cpu_s"], 3), round(c["plan_s"], 2), round(c["plan_cpu_s"], 2),
                         round(c["us_per_segment"], 1), round(c["load_1min"], 1)] for c in cost]))
    return cost


def blending_bench(options: argparse.Namespace) -> int:
    """Per-program goals, the override sweep, the dense-CAM stream and the planning cost; a table each."""
    from cnc_tools.bench.blending_override import override_sweep  # the bench's sections import this module
    from cnc_tools.bench.blending_stream import dense_cam

    quick = bool(options.quick)
    arc_s, figures = corpus_table(quick)
    sweep = override_sweep(quick)
    stream = dense_cam(options)
    cost = planning_table(quick)
    write_json(options.json, {"bench": "blending", "tolerance_mm": TOLERANCE_MM, "arc_s": arc_s,
                              "programs": figures, "override_sweep": sweep, "dense_cam": stream, "planning": cost,
                              "machine": machine()})
    return 0
