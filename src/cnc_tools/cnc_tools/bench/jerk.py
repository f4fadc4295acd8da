"""Bench ``jerk``: the jerk-limited modes on the blending bench's programs, and the FIR mode's override sweep.

Per program of :mod:`cnc_tools.bench.blending_corpus`, at the blending bench's tolerance, limits and jerk limit
(:data:`cnc_tools.bench.blending_limits.MAX_JERK_M_S3`, the acceleration limit reached in 25 ms), for
``jerk_mode`` ``fir`` (:mod:`cnc_contour_control.motion.jerk_fir`), ``scurve``
(:mod:`cnc_contour_control.motion.jerk_plan`) and ``quickest`` (the mode it ran in its label; ``fir`` is the default):
the cycle time over toppra's (v, a) bound on the blended path
of the planner without a jerk limit (:mod:`cnc_tools.bench.time_optimal`; toppra has no jerk limit, so its time
is a lower bound), over that planner's time and over exact stop (G61) without a jerk limit; the worst velocity,
acceleration and jerk ratio by finite differences of the reference every 1 ms
(:func:`cnc_contour_control.motion.reference_check.limit_ratios`) and the worst exact distance to the programmed
path over P, and the planning and sampling CPU time. Goals: every ratio <= 1 + 1e-9, dev/P <= 1, and within
``TOPPRA_GOAL`` of toppra on ``TOPPRA_PROGRAMS`` (a line gives them for ``quickest``). The override sweep
steps the FIR mode's live reference (the ratio ramps before the filter) under
:data:`cnc_tools.bench.blending_override.SCHEDULES`.
"""
from __future__ import annotations

import argparse
import dataclasses
import time
from typing import Any

import numpy as np

from cnc_contour_control.motion.feed_override import OverrideConfig
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.reference_check import limit_ratios, sample_reference
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.bench.blending import TOPPRA_GOAL, TOPPRA_PROGRAMS
from cnc_tools.bench.blending_corpus import CORPUS
from cnc_tools.bench.blending_limits import LIMIT_GOAL, SAMPLE_S, TOLERANCE_MM, bench_config, limits_for
from cnc_tools.bench.blending_override import _TAIL_TICKS, SCHEDULES, SWEEP_PROGRAMS, live_samples

MODES = ("fir", "scurve", "quickest")


def mode_figures(program: Program, mode: str) -> dict[str, Any]:
    """One jerk mode on ``program``: cycle time (s), worst v, a, jerk ratios, deviation over P, CPU time (s)."""
    started = time.process_time()
    limits = limits_for(program, jerk=True)
    interpolator, trajectory = sample_reference(program, limits, dataclasses.replace(bench_config(), jerk_mode=mode),
                                                SAMPLE_S)
    cpu_s = time.process_time() - started
    ratios = limit_ratios(trajectory.position_m, SAMPLE_S, limits)
    deviation_m = program.contour_distance(trajectory.position_m)[0]
    return {"cycle_s": interpolator.duration_s, "velocity_ratio": float(np.max(ratios.velocity)),
            "acceleration_ratio": float(np.max(ratios.acceleration)), "jerk_ratio": float(np.max(ratios.jerk)),
            "deviation_over_p": float(deviation_m.max()) / (TOLERANCE_MM * 1e-3), "cpu_s": cpu_s,
            "mode_used": interpolator.jerk_mode_used,
            "filter": None if interpolator.jerk_filter is None else dataclasses.asdict(interpolator.jerk_filter)}


def program_figures(program: Program, spacing_m: float = 2e-4) -> dict[str, Any]:
    """The modes (:data:`MODES`: both, and the quicker that ``quickest`` takes) on ``program`` beside toppra's
    bound, the planner without a jerk limit and exact stop (s)."""
    from cnc_tools.bench.time_optimal import time_optimal_s  # toppra: only when the table runs

    plain_limits = limits_for(program)
    plain = Interpolator(program, plain_limits, bench_config())
    return {"program": program.name, "segments": len(program.segments), "blended_s": plain.duration_s,
            "toppra_s": time_optimal_s(plain.program, plain_limits, spacing_m),
            "exact_stop_s": Interpolator(program, plain_limits, bench_config(0.0)).duration_s,
            **{mode: mode_figures(program, mode) for mode in MODES}}


def goals(f: dict[str, Any], mode: str) -> dict[str, bool | None]:
    """Each goal met or not for one mode's figures (None: no toppra goal for the program)."""
    m = f[mode]
    return {"limits": max(m["velocity_ratio"], m["acceleration_ratio"], m["jerk_ratio"]) <= LIMIT_GOAL,
            "P": m["deviation_over_p"] <= LIMIT_GOAL,
            "toppra": m["cycle_s"] <= TOPPRA_GOAL * f["toppra_s"] if f["program"] in TOPPRA_PROGRAMS else None}


def _row(f: dict[str, Any], mode: str) -> list[object]:
    m, met = f[mode], goals(f, mode)
    label = mode if mode != "quickest" else f"quickest: {m['mode_used']}"
    return [f["program"], label, f"{m['cycle_s']:.3f}", f"{m['cycle_s'] / f['toppra_s']:.4f}",
            f"{m['cycle_s'] / f['blended_s']:.4f}", f"{m['cycle_s'] / f['exact_stop_s']:.4f}", f"{m['cpu_s']:.3f}",
            *(f"{m[name]:.4f}" for name in ("velocity_ratio", "acceleration_ratio", "jerk_ratio", "deviation_over_p")),
            goal_text(bool(met["limits"] and met["P"])),
            "-" if met["toppra"] is None else goal_text(met["toppra"])]


def _quickest_goals(figures: list[dict[str, Any]]) -> str:
    """One line: ``quickest``'s goals met per goal program (limits, P and toppra), and which mode ran."""
    parts = []
    for f in figures:
        met = goals(f, "quickest")
        if met["toppra"] is not None:
            ok = bool(met["limits"] and met["P"] and met["toppra"])
            parts.append(f"{f['program']} ({f['quickest']['mode_used']}) {goal_text(ok)}")
    return f"jerk_mode quickest (fir is the default), every goal within {TOPPRA_GOAL} toppra: " + ", ".join(parts)


def sweep_figures(program: Program, schedule: str) -> dict[str, Any]:
    """The FIR mode's live reference under one override schedule: cycle time (s), worst ratios, deviation over P."""
    times, ratios, max_ratio = SCHEDULES[schedule]
    run = live_samples(program, OverrideConfig(max_ratio=max_ratio, schedule_times_s=times, schedule_ratios=ratios))
    found = limit_ratios(run.position_m, SAMPLE_S, limits_for(program, jerk=True))
    return {"program": program.name, "schedule": schedule, "max_ratio": max_ratio,
            "cycle_s": (len(run.ratio) - 1 - _TAIL_TICKS) * SAMPLE_S,
            "velocity_ratio": float(found.velocity.max()), "acceleration_ratio": float(found.acceleration.max()),
            "jerk_ratio": float(found.jerk.max()),
            "deviation_over_p": float(program.contour_distance(run.position_m)[0].max()) / (TOLERANCE_MM * 1e-3)}


def override_sweep(quick: bool) -> list[dict[str, Any]]:
    """Print and return the sweep over :data:`SWEEP_PROGRAMS` (the first only with ``quick``)."""
    names = SWEEP_PROGRAMS[:1] if quick else SWEEP_PROGRAMS
    figures = [sweep_figures(CORPUS[name][0](), schedule) for name in names for schedule in SCHEDULES]
    rows = [[f["program"], f["schedule"], f["max_ratio"], f"{f['cycle_s']:.3f}",
             *(f"{f[name]:.4f}" for name in ("velocity_ratio", "acceleration_ratio", "jerk_ratio", "deviation_over_p")),
             goal_text(max(f["velocity_ratio"], f["acceleration_ratio"], f["jerk_ratio"]) <= LIMIT_GOAL
                       and f["deviation_over_p"] <= LIMIT_GOAL)] for f in figures]
    print("override sweep, jerk_mode fir: 1 ms ticks, the ratio ramps before the filter")
    print(format_table(["program", "override", "planned for", "cycle s", "v ratio", "a ratio", "jerk ratio", "dev/P",
                        "limits, P"], rows))
    return figures


def jerk_bench(options: argparse.Namespace) -> int:
    """Both modes' table over the corpus and the override sweep (``--quick``: the quick programs, one sweep)."""
    quick = bool(getattr(options, "quick", False))
    figures = [program_figures(make()) for make, in_quick in CORPUS.values() if in_quick or not quick]
    print(f"jerk-limited modes at P {TOLERANCE_MM} mm, the blending bench's limits and jerk limit; times in s; "
          f"ratios by finite differences every {SAMPLE_S * 1e3:g} ms; toppra on the (v, a) planner's blended path")
    print(format_table(["program", "mode", "cycle s", "/toppra", "/no jerk", "/G61", "CPU s", "v ratio", "a ratio",
                        "jerk ratio", "dev/P", "limits, P", f"<={TOPPRA_GOAL} toppra"],
                       [_row(f, mode) for f in figures for mode in MODES]))
    print(_quickest_goals(figures))
    sweep = override_sweep(quick)
    write_json(getattr(options, "json", None), {"bench": "jerk", "tolerance_mm": TOLERANCE_MM, "programs": figures,
                                                "override_sweep": sweep, "machine": machine()})
    return 0
