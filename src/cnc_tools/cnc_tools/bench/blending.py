"""Bench ``blending``: corner blending within a path tolerance on a corpus of CAM-like programs.

Per program of :mod:`cnc_tools.bench.blending_corpus`, at ``path_tolerance_mm``
0.01, paper 000's limits (2000 mm/min, 250 mm/s² per axis) and arcs planned with the
combined acceleration budget (``arc_combined_budget``, centripetal fraction 0.8,
the default 8 speed bands per arc: ``arc_speed_bands``; :mod:`cnc_contour_control.motion.arc_budget`):

- worst velocity and acceleration ratio per axis, analytic and finite
  difference of the sampled positions (goal <= 1 + 1e-9);
- worst deviation of the reference from the programmed path, measured exactly
  to the programmed segments each sample's planned segment comes from
  (``BlendedProgram.local_deviation_m``, an upper bound of the contour distance),
  beside the tolerance;
- cycle time beside the exact-stop time, the time-optimal limit on the same
  blended path (``toppra``, :mod:`cnc_tools.bench.time_optimal`; goal within
  10 %) and, for the polygon circles, the true arc's time (goal within 10 %);
- planning time per segment against program length (polygons of 0.2 mm sides;
  CPU time, so that other processes' load does not count, beside the 1-minute load
  average; planning is NumPy over whole programs: :mod:`cnc_contour_control.motion.plan_arrays`,
  :mod:`cnc_contour_control.motion.blend_assembly`, :mod:`cnc_contour_control.motion.segment_batch`), whole and
  streaming
  (a window of ``STREAM_WINDOW`` segments, :mod:`cnc_contour_control.motion.plan_stream`): CPU time to the first
  sample beside the CPU time of the whole plan.
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
from cnc_contour_control.motion.interpolation import AxisLimits, Interpolator, InterpolatorConfig
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.bench.blending_corpus import CORPUS, polygon, true_circle
from cnc_tools.bench.time_optimal import time_optimal_s

TOLERANCE_MM = 0.01
#: The planner options of the bench: arcs with the combined acceleration budget (``arc_budget``) and 80 % of it
#: for the centripetal part (the split budget's default 50 % left the arc chain at 1.24x toppra).
CENTRIPETAL_FRACTION = 0.8
MAX_VELOCITY_M_S = 2000.0 / 60000.0
MAX_ACCELERATION_M_S2 = 0.25
#: Sample period of the checks, s. The finite-difference acceleration's rounding floor is about
#: 4 ulp(position) / dt**2: 1.4e-9 of 250 mm/s^2 at 0.2 ms, 6e-11 at 1 ms (paper 000 samples at 10 ms).
SAMPLE_S = 1e-3
LIMIT_GOAL = 1.0 + 1e-9
TIME_GOAL = 1.10
#: The streaming planner's window in the planning-cost table, planned segments.
STREAM_WINDOW = 200
PLAN_SIZES = (1_000, 10_000, 200_000)


def limits_for(program: Program) -> AxisLimits:
    """Paper 000's limits on every axis of ``program``."""
    return AxisLimits((MAX_VELOCITY_M_S,) * program.n_axes, (MAX_ACCELERATION_M_S2,) * program.n_axes)


def bench_config(tolerance_mm: float = TOLERANCE_MM) -> InterpolatorConfig:
    """The planner options of the bench (path tolerance, combined arc budget)."""
    return InterpolatorConfig(path_tolerance_mm=tolerance_mm, arc_combined_budget=True,
                              arc_centripetal_fraction=CENTRIPETAL_FRACTION)


def limit_ratios(interpolator: Interpolator, dt_s: float = SAMPLE_S) -> tuple[np.ndarray, np.ndarray]:
    """Worst velocity and acceleration ratio to the limit per axis, ``(n_axes,)`` each.

    The worst of the analytic value and the finite difference of positions sampled every ``dt_s``.
    """
    times = np.arange(-3 * dt_s, interpolator.duration_s + 3 * dt_s, dt_s)
    trajectory = interpolator.sample_array(times)
    v_max = np.asarray(interpolator.limits.max_velocity_m_s)
    a_max = np.asarray(interpolator.limits.max_acceleration_m_s2)
    velocity = np.vstack([np.abs(trajectory.velocity_m_s), np.abs(np.diff(trajectory.position_m, axis=0)) / dt_s])
    acceleration = np.vstack([np.abs(trajectory.acceleration_m_s2),
                              np.abs(np.diff(trajectory.position_m, 2, axis=0)) / dt_s**2])
    return velocity.max(axis=0) / v_max, acceleration.max(axis=0) / a_max


def worst_deviation_m(interpolator: Interpolator, dt_s: float = SAMPLE_S) -> float:
    """Largest distance of the sampled reference from the programmed path, m."""
    trajectory = interpolator.sample_array(np.arange(0.0, interpolator.duration_s + dt_s, dt_s))
    return float(np.max(interpolator.blended.local_deviation_m(trajectory.position_m, trajectory.segment_index)))


def program_figures(program: Program, spacing_m: float) -> dict[str, Any]:
    """The bench's figures for one program."""
    limits, config = limits_for(program), bench_config()
    started = time.perf_counter()
    interpolator = Interpolator(program, limits, config)
    plan_s = time.perf_counter() - started
    velocity, acceleration = limit_ratios(interpolator)
    optimal_s = time_optimal_s(interpolator.program, limits, spacing_m)
    return {"program": program.name, "segments": len(program.segments), "blends": len(interpolator.blended.blends),
            "stops": int(np.count_nonzero(interpolator.junction_speeds_m_s == 0.0)),
            "cycle_s": interpolator.duration_s, "exact_stop_s": Interpolator(program, limits).duration_s,
            "toppra_s": optimal_s, "plan_s": plan_s,
            "velocity_ratio": velocity.tolist(), "acceleration_ratio": acceleration.tolist(),
            "deviation_um": worst_deviation_m(interpolator) * 1e6}


def _row(f: dict[str, Any], arc_s: float) -> list[object]:
    worst = max(max(f["velocity_ratio"]), max(f["acceleration_ratio"]))
    to_arc: Any = f["cycle_s"] / arc_s if f["program"].startswith("circle") else ""  # a ratio, or "" (no circle)
    return [f["program"], f["segments"], f["blends"], f["stops"], round(f["exact_stop_s"], 2), round(f["cycle_s"], 3),
            round(f["toppra_s"], 3), round(f["cycle_s"] / f["toppra_s"], 3), to_arc and round(to_arc, 3),
            " ".join(f"{v:.6f}" for v in f["velocity_ratio"]), " ".join(f"{a:.6f}" for a in f["acceleration_ratio"]),
            round(f["deviation_um"], 3), goal_text(worst <= LIMIT_GOAL and f["deviation_um"] <= TOLERANCE_MM * 1e3
                                                   * LIMIT_GOAL),
            goal_text(f["cycle_s"] <= TIME_GOAL * f["toppra_s"] and (to_arc == "" or to_arc <= TIME_GOAL))]


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


def blending_bench(options: argparse.Namespace) -> int:
    """Limits, tolerance, cycle time against toppra and the arc, planning cost; a table per part."""
    quick = bool(options.quick)
    spacing_m = 2e-4 if quick else 5e-5
    arc_s = Interpolator(true_circle(), limits_for(true_circle()), bench_config(0.0)).duration_s
    figures = [program_figures(make(), spacing_m) for make, in_quick in CORPUS.values() if in_quick or not quick]
    print(f"blending at {TOLERANCE_MM} mm, {MAX_VELOCITY_M_S * 60000:.0f} mm/min and {MAX_ACCELERATION_M_S2 * 1e3:.0f} "
          f"mm/s^2 per axis; arcs: combined budget, centripetal fraction {CENTRIPETAL_FRACTION}, "
          f"{bench_config().arc_speed_bands} speed bands; true arc R 20 mm: "
          f"{arc_s:.3f} s; toppra grid {spacing_m * 1e3:g} mm")
    print(format_table(["program", "segs", "blends", "stops", "stop s", "cycle s", "toppra s", "/toppra", "/arc",
                        "v ratio per axis", "a ratio per axis", "dev um", "limits+tol", "time 10 %"],
                       [_row(f, arc_s) for f in figures]))
    cost = planning_cost(PLAN_SIZES[:2] if quick else PLAN_SIZES, (None, STREAM_WINDOW))
    print(format_table(["segments", "plan", "first sample CPU s", "plan wall s", "plan CPU s", "CPU us/segment",
                        "load (1 min)"],
                       [[c["segments"], f"stream W={c['window']}" if c["streaming"] else "whole",
                         round(c["first_sample_cpu_s"], 3), round(c["plan_s"], 2), round(c["plan_cpu_s"], 2),
                         round(c["us_per_segment"], 1), round(c["load_1min"], 1)] for c in cost]))
    write_json(options.json, {"bench": "blending", "tolerance_mm": TOLERANCE_MM, "arc_s": arc_s,
                              "programs": figures, "planning": cost, "machine": machine()})
    return 0
