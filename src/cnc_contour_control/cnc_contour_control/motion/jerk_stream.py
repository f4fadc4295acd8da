"""The FIR jerk mode streamed (``jerk_mode: fir``, ``look_ahead_segments`` below the program's length; ROS-free).

:class:`~cnc_contour_control.motion.plan_stream.StreamPlan` plans the (v, a) plan a chunk at a time as without a
jerk limit, with fir's planning changes applied per chunk (:mod:`~cnc_contour_control.motion.jerk_fir`): each
block's arcs capped as it is blended (:func:`~cnc_contour_control.motion.jerk_fir.capped_program`, in
``plan_blocks.PlanBlocks``) and each corner stop of a chunk held (:func:`chunk_holds_s`, ``stop_holds_s`` of the
chunk and the segment before it). Before a chunk is published, :func:`chunk_deviation_m` measures the filtered
reference at the multiples of the filter's period whose window ends in the chunk (its first ``n - 1`` samples
reach back into the chunk before, kept for this) against the programmed segments its samples come from, as
``within_tolerance`` does for the whole program. Over ``P`` the chunk is planned again with smaller caps
(:func:`stream_attempts`), then with every junction a stop held the filter's window. A chunk is published only
once the next one is planned and checked (the samples across their junction are the next one's): if the next
is over ``P`` even with stops, the one before is planned again to end at rest, and the next from that rest,
held. The tool never reaches a chunk that is not published. A chunk still over ``P`` is published and counted
(``StreamPlan.over_tolerance_chunks``; the whole plan would fall back to ``scurve``, which needs the whole
program).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cnc_contour_control.motion.geometry import Program, Segment
from cnc_contour_control.motion.jerk_filter import moving_average_rows
from cnc_contour_control.motion.jerk_fir import FirSettings, fir_attempts, stop_holds_s
from cnc_contour_control.motion.plan_arrays import Phases
from cnc_contour_control.motion.points import FloatArray


@dataclass
class Chunk:
    """A planned chunk: segments ``j .. j + commit - 1``, its junction speeds (m/s, from ``j``), its phases (from 0),
    the attempt that planned it, its filtered reference's deviation (m), its start (s), the holds (s) at its first
    junction and at the next chunk's first."""

    j: int
    commit: int
    speeds: FloatArray
    last: bool
    phases: Phases
    attempt: int
    deviation_m: float
    start_s: float
    hold_first_s: float
    hold_next_s: float

    @property
    def end_s(self) -> float:
        """Its end in profile time, s."""
        return self.start_s + float(self.phases.start_s[-1])

    def after(self, kept: Phases) -> Phases:
        """``kept`` (published, global) followed by this chunk's phases."""
        return Phases(np.concatenate((kept.start_s[:-1], self.phases.start_s + self.start_s)),
                      np.concatenate((kept.s0_m, self.phases.s0_m)), np.concatenate((kept.v0_m_s, self.phases.v0_m_s)),
                      np.concatenate((kept.accel_m_s2, self.phases.accel_m_s2)),
                      np.concatenate((kept.segment, self.phases.segment + self.j)))


def stream_attempts(settings: FirSettings) -> tuple[FirSettings, FirSettings]:
    """The caps a stream plans with and those it plans a chunk over P again with: of ``fir_attempts``' attempts
    that keep the blends, the first and the last that move no corner out (a pushed corner moves a line by its
    neighbours two segments away, across a block's seam)."""
    kept = [fir for fir, blend_m in fir_attempts(settings, 1.0)
            if blend_m > 0.0 and getattr(fir, "push_m", 0.0) == 0.0]
    return kept[0], kept[-1]


def chunk_holds_s(segments: Sequence[Segment], speeds_m_s: FloatArray, accel_m_s2: FloatArray, before: bool,
                  corner_rad: float, settings: FirSettings) -> FloatArray:
    """The hold (s) at each junction before the chunk's segments: ``(len(speeds_m_s) - 1,)``.

    ``segments``: the chunk's, after the segment before it if ``before``; ``speeds_m_s``: the chunk's junction
    speeds (its first junction to its last, ``commit + 1``); ``accel_m_s2``: each of ``segments``' tangential
    acceleration (m/s²).
    """
    program = Program("chunk", tuple(f"a{k}" for k in range(len(segments[0].start_m))), tuple(segments))
    commit = len(speeds_m_s) - 1
    speeds = np.concatenate(([0.0], speeds_m_s[:commit], [0.0])) if before else np.append(speeds_m_s[:commit], 0.0)
    holds = stop_holds_s(program, speeds, corner_rad, settings, accel_m_s2)
    return holds[1:commit + 1] if before else holds[:commit]


def _positions(phases: Phases, segments: Any, n_axes: int, times_s: FloatArray) -> tuple[FloatArray, np.ndarray]:
    """The plan's positions (m) and planned segment (global index) at ``times_s`` (held at the phases' ends)."""
    clipped = np.clip(times_s, phases.start_s[0], phases.start_s[-1])
    k = np.maximum(np.searchsorted(phases.start_s[:-1], clipped, side="right") - 1, 0)
    dt = clipped - phases.start_s[k]
    s_local = phases.s0_m[k] + phases.v0_m_s[k] * dt + 0.5 * phases.accel_m_s2[k] * dt * dt
    index = phases.segment[k]
    position = np.zeros((times_s.size, n_axes))
    for i in np.unique(index).tolist():
        rows = np.flatnonzero(index == i)
        segment = segments[i]
        position[rows] = segment.point(np.clip(s_local[rows], 0.0, segment.length_m))
    return position, index


def chunk_deviation_m(kept: Phases, new: Phases, segments: Any, source: Any, programmed: Program,
                      settings: FirSettings, last: bool) -> float:
    """The largest distance (m) of the filtered reference from the programmed path over the new chunk.

    ``kept``: the published phases (global times; ``start_s`` ends at the chunk's start), ``new``: the chunk's
    (global times and segments); ``segments``/``source``: planned segment and its programmed segment by global
    index. Samples at ``m T`` from the chunk's start to before its end (with ``last``, to the filter's drain).
    """
    n, period = settings.taps, settings.period_s
    begin_s, end_s = float(new.start_s[0]), float(new.start_s[-1])
    first_m = math.ceil(begin_s / period - 1e-9)
    stop_m = math.ceil((end_s + (n if last else 0) * period) / period - 1e-9)
    if stop_m <= first_m:
        return 0.0
    phases = Phases(np.concatenate((kept.start_s[:-1], new.start_s)), np.concatenate((kept.s0_m, new.s0_m)),
                    np.concatenate((kept.v0_m_s, new.v0_m_s)), np.concatenate((kept.accel_m_s2, new.accel_m_s2)),
                    np.concatenate((kept.segment, new.segment)))
    times = period * np.arange(first_m - (n - 1), stop_m, dtype=np.float64)
    raw, index = _positions(phases, segments, programmed.n_axes, np.maximum(times, 0.0))
    points = moving_average_rows(raw, n)
    sources = np.asarray(source[index], dtype=np.intp)
    first = np.maximum(sources[:points.shape[0]] - 1, 0)
    last_source = sources[n - 1:]
    distance = np.full(points.shape[0], np.inf)
    if not points.shape[0]:
        return 0.0
    for j in range(int(first.min()), int(last_source.max()) + 1):  # the chunk's programmed segments only
        rows = slice(int(np.searchsorted(last_source, j, side="left")), int(np.searchsorted(first, j, side="right")))
        if rows.start < rows.stop:
            near = programmed.segments[j].nearest(points[rows])[0]
            distance[rows] = np.minimum(distance[rows], near)
    return float(distance.max(initial=0.0))
