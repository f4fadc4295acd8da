"""Bench ``blending``, override sweep: feed overrides from 10 % to 200 %, held and changed mid-path.

Per program and schedule the reference is stepped at 1 ms ticks as the interpolator node steps it
(:class:`~cnc_contour_control.motion.feed_override.LiveReference`: the profile planned for the largest
ratio, ``max_ratio`` 2, by :func:`~cnc_contour_control.motion.feed_override.planning_limits`; the applied
ratio ramps towards each request within the limits; ``clamp_feed``: planned for 200 %, a feed over half the
velocity limit is slowed to it, also at 100 %). The override only retimes the planned path; the rows give each
tick's exact distance to the programmed path (``Program.contour_distance``) over P, the worst v, a and jerk
ratios of the ticks (:func:`cnc_tools.bench.blending.sampled_ratios`) and the cycle time, beside the 100 % row
planned for ``max_ratio`` 1 (what planning for 200 % costs at 100 %). With the jerk limit the planner runs
``jerk_mode`` fir, the mode whose override ramps come out jerk-limited (``quickest`` may take ``scurve``, whose
ramps are not).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_tools.analysis.tables import format_table, goal_text
from cnc_tools.bench.blending_corpus import CORPUS
from cnc_tools.bench.blending_limits import (
    LIMIT_GOAL,
    SAMPLE_S,
    TOLERANCE_MM,
    bench_config,
    limits_for,
    sampled_ratios,
)

#: Programs of the sweep (the first alone with ``--quick``).
SWEEP_PROGRAMS = ("zigzag-150", "circle-360-gon", "arc-scallops")
MAX_RATIO = 2.0
#: Schedule name -> (times s, ratios, max_ratio planned for).
SCHEDULES: dict[str, tuple[tuple[float, ...], tuple[float, ...], float]] = {
    "10 %": ((0.0,), (0.1,), MAX_RATIO),
    "50 %": ((0.0,), (0.5,), MAX_RATIO),
    "100 %": ((0.0,), (1.0,), MAX_RATIO),
    "200 %": ((0.0,), (2.0,), MAX_RATIO),
    "changes mid-path": ((0.0, 0.5, 1.2, 1.9, 2.4, 3.0), (1.0, 2.0, 0.1, 1.5, 0.5, 2.0), MAX_RATIO),
    "100 %, planned for 100 %": ((0.0,), (1.0,), 1.0),
}
#: Ticks after the end (at rest), so that the differences see the stop.
_TAIL_TICKS = 3


@dataclass(frozen=True)
class LiveRun:
    """Every tick's reference: ``position_m``, ``velocity_m_s``, ``acceleration_m_s2`` ``(M, n_axes)``, ``segment``
    (planned segment index) and ``ratio`` (the applied override) ``(M,)``; the interpolator that planned it."""

    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    segment: np.ndarray
    ratio: np.ndarray
    interpolator: Interpolator


def live_samples(program: Program, config: OverrideConfig, dt_s: float = SAMPLE_S,
                 max_ticks: int = 2_000_000) -> LiveRun:
    """The reference of every tick of ``dt_s`` under ``config``'s schedule until the end, plus a few at rest.

    Raises :class:`FaultError` if the end is not reached in ``max_ticks``.
    """
    live = LiveReference(program, limits_for(program, jerk=True), replace(bench_config(), clamp_feed=True,
                                                                          jerk_mode="fir"), config)
    dt_ns = round(dt_s * 1e9)
    rows: list[tuple[np.ndarray, np.ndarray, np.ndarray, int, float]] = []
    tail = 0
    for tick in range(max_ticks):
        stamp_ns = tick * dt_ns
        sample = live.step(stamp_ns, live.request(stamp_ns, 1.0))
        rows.append((sample.position_m, sample.velocity_m_s, sample.acceleration_m_s2, sample.segment_index,
                     sample.feed_override_ratio))
        tail += int(sample.done)
        if tail > _TAIL_TICKS:
            break
    else:
        raise FaultError(f"{program.name!r} did not end within {max_ticks} ticks of {dt_s} s")
    position, velocity, acceleration, segment, ratio = zip(*rows)
    return LiveRun(np.array(position), np.array(velocity), np.array(acceleration), np.array(segment, dtype=np.intp),
                   np.array(ratio), live.interpolator)


def sweep_figures(program: Program, schedule: str) -> dict[str, Any]:
    """One program under one schedule: cycle time, deviation over P, worst v, a and jerk ratios per axis."""
    times, ratios, max_ratio = SCHEDULES[schedule]
    run = live_samples(program, OverrideConfig(max_ratio=max_ratio, schedule_times_s=times, schedule_ratios=ratios))
    deviation_m = program.contour_distance(run.position_m)[0]  # the jerk filter's samples lag their segment index
    found = sampled_ratios(run.position_m, run.velocity_m_s, run.acceleration_m_s2, SAMPLE_S, program.n_axes)
    return {"program": program.name, "schedule": schedule, "max_ratio": max_ratio,
            "cycle_s": (len(run.ratio) - 1 - _TAIL_TICKS) * SAMPLE_S,
            "deviation_over_p": float(np.max(deviation_m)) / (TOLERANCE_MM * 1e-3),
            **{name: value.tolist() for name, value in found.items()}}


def override_sweep(quick: bool) -> list[dict[str, Any]]:
    """Print and return the sweep: every schedule on every sweep program (the first only with ``quick``)."""
    names = SWEEP_PROGRAMS[:1] if quick else SWEEP_PROGRAMS
    figures = [sweep_figures(CORPUS[name][0](), schedule) for name in names for schedule in SCHEDULES]
    rows = [[f["program"], f["schedule"], f["max_ratio"], f"{f['cycle_s']:.3f}", f"{f['deviation_over_p']:.4f}",
             " ".join(f"{v:.4f}" for v in f["velocity_ratio"]), " ".join(f"{a:.4f}" for a in f["acceleration_ratio"]),
             " ".join(f"{j:.4f}" for j in f["jerk_ratio"]), goal_text(f["deviation_over_p"] <= LIMIT_GOAL),
             goal_text(max(f["velocity_ratio"] + f["acceleration_ratio"]) <= LIMIT_GOAL),
             goal_text(max(f["jerk_ratio"]) <= LIMIT_GOAL)] for f in figures]
    print(f"override sweep: 1 ms ticks, profile planned for max_ratio {MAX_RATIO} unless said")
    print(format_table(["program", "override", "planned for", "cycle s", "dev/P", "v ratio per axis",
                        "a ratio per axis", "jerk ratio per axis", "dev<=P", "v,a<=1", "jerk<=1"], rows))
    return figures
