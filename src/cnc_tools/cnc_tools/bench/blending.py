"""Bench ``blending``: corner blending within a path tolerance on a corpus of CAM-like programs.

Per program of :mod:`cnc_tools.bench.blending_corpus`, the planner as shipped: ``path_tolerance_mm`` 0.01,
paper 000's limits (2000 mm/min, 250 mm/s² per axis), a machine tool's jerk limit (``MAX_JERK_M_S3``: the
acceleration limit reached in 25 ms, given to the planner: ``limits_for(program, True)``) and the default
options (``BEST_OPTIONS`` in :mod:`~cnc_tools.bench.blending_limits`; ``jerk_mode`` fir):

- worst velocity, acceleration and jerk ratio per axis on the sampled reference, each the larger of the
  analytic value and the finite difference (:func:`sampled_ratios`; goal <= 1 + 1e-9);
- worst exact distance of the sampled reference from the programmed path (``Program.contour_distance``) over
  the tolerance P (goal <= 1);
- cycle time over the exact-stop time with the same jerk limit (G61: tolerance 0, same limits, which the
  planner plans in ``scurve``; goal <= 1 on every program), and, as information, over exact stop without a
  jerk limit; over the time-optimal (v, a) bound (``toppra``, :mod:`cnc_tools.bench.time_optimal`) on the
  blended path of the planner without a jerk limit (goal <= ``TOPPRA_GOAL`` on the circles, the pocket and the
  raster: toppra has no jerk limit, so its time is a lower bound), beside that planner's own cycle time;
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
    SAMPLE_S,
    TOLERANCE_MM,
    bench_config,
    limits_for,
    reference_ratios,
)

#: Cycle time over toppra's (v, a) bound, on :data:`TOPPRA_PROGRAMS`.
TOPPRA_GOAL = 1.15
TOPPRA_PROGRAMS = ("circle-36-gon", "circle-360-gon", "circle-3600-gon", "pocket", "raster-3axis")
#: The streaming planner's window in the planning-cost table, planned segments.
STREAM_WINDOW = 200
PLAN_SIZES = (1_000, 10_000, 200_000)
#: ``--quick``: the deviation's sample period, s (the exact contour distance of the pocket's 1 ms samples takes
#: 7 s of CPU; the whole bench samples every ``SAMPLE_S``).
QUICK_DEVIATION_S = 0.01


def program_figures(program: Program, spacing_m: float, deviation_dt_s: float = SAMPLE_S) -> dict[str, Any]:
    """The bench's figures for one program (toppra's grid ``spacing_m``; the deviation sampled every
    ``deviation_dt_s``)."""
    from cnc_tools.bench.time_optimal import time_optimal_s  # toppra: only when the corpus table runs

    # The planner as shipped: the jerk limit given, the default jerk_mode (fir). fir's corners are not in
    # Interpolator.program, so toppra's (v, a) bound is taken on the blended path of the planner without it.
    limits, plain_limits = limits_for(program, True), limits_for(program)
    started = time.process_time()
    interpolator = Interpolator(program, limits, bench_config())
    plan_s = time.process_time() - started
    ratios = reference_ratios(interpolator)
    trajectory = interpolator.sample_array(np.arange(0.0, interpolator.duration_s + deviation_dt_s, deviation_dt_s))
    deviation_m = float(np.max(program.contour_distance(trajectory.position_m)[0]))
    plain = Interpolator(program, plain_limits, bench_config())
    exact_stop = Interpolator(program, limits, bench_config(0.0))
    return {"program": program.name, "segments": len(program.segments), "blends": len(interpolator.blended.blends),
            "jerk_mode_used": interpolator.jerk_mode_used, "cycle_s": interpolator.duration_s,
            "exact_stop_s": exact_stop.duration_s, "exact_stop_mode": exact_stop.jerk_mode_used,
            "exact_stop_no_jerk_s": Interpolator(program, plain_limits, bench_config(0.0)).duration_s,
            "no_jerk_s": plain.duration_s, "toppra_s": time_optimal_s(plain.program, plain_limits, spacing_m),
            "plan_cpu_s": plan_s, **{name: value.tolist() for name, value in ratios.items()},
            "deviation_over_p": deviation_m / (TOLERANCE_MM * 1e-3)}


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
    return [f["program"], f["segments"], f["blends"], f["jerk_mode_used"], f"{f['exact_stop_s']:.3f}",
            f"{f['exact_stop_no_jerk_s']:.3f}", f"{f['cycle_s']:.3f}", f"{f['no_jerk_s']:.3f}", f"{f['toppra_s']:.3f}",
            f"{f['cycle_s'] / f['toppra_s']:.4f}", f"{f['cycle_s'] / f['exact_stop_s']:.4f}",
            f"{f['cycle_s'] / f['exact_stop_no_jerk_s']:.4f}",
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
    deviation_dt_s = QUICK_DEVIATION_S if quick else SAMPLE_S
    figures = [program_figures(make(), spacing_m, deviation_dt_s) for make, in_quick in CORPUS.values()
               if in_quick or not quick]
    config = bench_config()
    print(f"blending at P = {TOLERANCE_MM} mm, {MAX_VELOCITY_M_S * 60000:.0f} mm/min, "
          f"{MAX_ACCELERATION_M_S2 * 1e3:.0f} mm/s^2 and {MAX_JERK_M_S3 * 1e3:.0f} mm/s^3 per axis (jerk limit given); "
          f"the shipped options (jerk_mode {config.jerk_mode}; arcs: "
          f"combined budget {config.arc_combined_budget}, centripetal fraction {config.arc_centripetal_fraction}, "
          f"{config.arc_speed_bands} speed bands); true arc R 20 mm: {arc_s:.3f} s; toppra grid {spacing_m * 1e3:g} mm "
          f"on the blended path without the jerk limit; G61: exact stop with the jerk limit (scurve), G61 no jerk: "
          f"without; dev: exact distance to the programmed path every {deviation_dt_s * 1e3:g} ms")
    print(format_table(["program", "segs", "blends", "mode", "G61 s", "G61 no jerk s", "cycle s", "no jerk s",
                        "toppra s", "/toppra", "/G61", "/G61 no jerk", "dev/P",
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
