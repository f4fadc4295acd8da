"""Bench ``jerk``: the jerk-limited planner mode's cycle time on the blending bench's programs.

Per program of :mod:`cnc_tools.bench.blending_corpus`, at the blending bench's tolerance, limits and jerk limit
(:data:`cnc_tools.bench.blending_limits.MAX_JERK_M_S3`, the acceleration limit reached in 25 ms): the cycle
time of the
jerk-limited mode (:mod:`cnc_contour_control.motion.jerk_plan`) beside the planner without a jerk limit at the
same tolerance, beside exact stop (G61) without a jerk limit and with it (the mode at P 0); the corners
passed at speed; the worst velocity,
acceleration and jerk ratio by finite differences of the reference sampled every 1 ms
(:func:`cnc_contour_control.motion.reference_check.limit_ratios`) and the worst deviation over P (exact, to the
programmed segment of each sample).
"""
from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.reference_check import limit_ratios, sample_reference
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.bench.blending_corpus import CORPUS
from cnc_tools.bench.blending_limits import LIMIT_GOAL, SAMPLE_S, TOLERANCE_MM, bench_config, limits_for


def program_figures(program: Program) -> dict[str, Any]:
    """Cycle times (s) of the three plans, corners at speed, worst limit ratios and deviation over P of one program."""
    started = time.process_time()
    jerk_limits = limits_for(program, jerk=True)
    interpolator, trajectory = sample_reference(program, jerk_limits, bench_config(), SAMPLE_S)
    plan_s = time.process_time() - started
    ratios = limit_ratios(trajectory.position_m, SAMPLE_S, jerk_limits)
    deviation = interpolator.blended.local_deviation_m(trajectory.position_m, trajectory.segment_index)
    plain = limits_for(program)
    corners = interpolator.junction_speeds_m_s[1:-1]
    return {"program": program.name, "segments": len(program.segments), "jerk_s": interpolator.duration_s,
            "blended_s": Interpolator(program, plain, bench_config()).duration_s,
            "exact_stop_s": Interpolator(program, plain, bench_config(0.0)).duration_s,
            "jerk_exact_stop_s": Interpolator(program, jerk_limits, bench_config(0.0)).duration_s,
            "corners_at_speed": int(np.count_nonzero(corners > 0.0)), "junctions": len(corners),
            "velocity_ratio": float(np.max(ratios.velocity)), "acceleration_ratio": float(np.max(ratios.acceleration)),
            "jerk_ratio": float(np.max(ratios.jerk)),
            "deviation_over_p": float(deviation.max()) / (TOLERANCE_MM * 1e-3), "cpu_s": plan_s}


def _row(f: dict[str, Any]) -> list[object]:
    limits_met = max(f["velocity_ratio"], f["acceleration_ratio"], f["jerk_ratio"]) <= LIMIT_GOAL
    return [f["program"], f["segments"], round(f["jerk_s"], 3), round(f["blended_s"], 3), round(f["exact_stop_s"], 3),
            round(f["jerk_s"] / f["blended_s"], 4), round(f["jerk_s"] / f["exact_stop_s"], 4),
            round(f["jerk_s"] / f["jerk_exact_stop_s"], 4),
            f"{f['corners_at_speed']}/{f['junctions']}", round(f["velocity_ratio"], 4),
            round(f["acceleration_ratio"], 4), round(f["jerk_ratio"], 4), round(f["deviation_over_p"], 4),
            goal_text(limits_met and f["deviation_over_p"] <= LIMIT_GOAL)]


def jerk_bench(options: argparse.Namespace) -> int:
    """The table of :func:`program_figures` over the corpus (``--quick``: the quick blending bench's programs)."""
    quick = bool(getattr(options, "quick", False))
    figures = [program_figures(make()) for make, in_quick in CORPUS.values() if in_quick or not quick]
    print(f"jerk-limited mode at P {TOLERANCE_MM} mm, the blending bench's limits and jerk limit; times in s; "
          f"ratios by finite differences every {SAMPLE_S * 1e3:g} ms")
    print(format_table(["program", "segments", "jerk", "no jerk", "G61", "/no jerk", "/G61", "/jerk G61",
                        "corners at speed",
                        "v ratio", "a ratio", "jerk ratio", "dev/P", "limits, P"], [_row(f) for f in figures]))
    write_json(getattr(options, "json", None), {"bench": "jerk", "tolerance_mm": TOLERANCE_MM, "programs": figures,
                                                "machine": machine()})
    return 0
