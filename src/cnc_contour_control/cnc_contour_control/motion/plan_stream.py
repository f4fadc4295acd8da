"""Streaming planning: the feed profile planned chunk by chunk, a look-ahead window ahead of the tool.

A controller's look-ahead buffer of ``W`` segments (``look_ahead_segments``) plans the speed at a junction from
the segments it sees ahead and a stop at the last one's end (:func:`~cnc_contour_control.motion.plan_arrays.
look_ahead_caps_m_s`). :class:`StreamPlan` does the same lazily: to commit the planned segments ``J .. J + C - 1``
(a chunk, ``C = max(W, MIN_CHUNK_SEGMENTS)``) it

1. blends the programmed segments it needs (:func:`blending.blend_program` on a slice with two segments of
   context before and one after: a corner's blend depends only on its two neighbours, a blend arc's start on
   the planned path's end before it), and computes their limits (``plan_banded_limits``);
2. runs the junction passes over ``J .. J + C + W`` from the committed entry speed at ``J`` to a stop at the
   window's end, with the look-ahead caps;
3. commits the speeds at ``J + 1 .. J + C`` and the chunk's phases (``jerk_mode`` fir: its checks first,
   :mod:`~cnc_contour_control.motion.jerk_stream`).

Why this equals the whole plan with the same window (in exact arithmetic): the backward pass's speed at
junction ``k`` is the least over ``m >= k`` of ``sqrt(cap_m² + Σ_{k..m-1} 2 a_i L_i)``; every term with
``m >= k + W`` and every look-ahead cap beyond ``k`` is at least junction ``k``'s own look-ahead cap (reaches
are non-negative and increasing; a banded segment's reach is never below the lowest band's, which the caps
use), so junction ``k``'s speed depends on the caps at ``k .. k + W - 1`` only: a stop at ``J + C + W`` changes
nothing at or before ``J + C``. The forward pass is causal. Rounding differs (cumulative sums over a chunk, not
the program): the samples agree to 1e-12 (``test_plan_stream.py``). Committed segments never change.

What differs from planning whole: a segment the limits refuse (a feed over them, ``clamp_feed`` false) raises
its :class:`ProgramError` when the stream reaches it, from :meth:`StreamPlan.extend_to`, not at construction.

On line (:class:`~cnc_contour_control.motion.feed_override.LiveReference`) a
:class:`~cnc_contour_control.motion.plan_background.BackgroundPlanner` plans the chunks in a thread ahead of
the tool (a tick samples, never plans) and calls :meth:`StreamPlan.forget_before`, which drops the phases
and planned segments behind the tool (``FORGET_PHASES`` at a time): the lists and arrays hold the window, the
chunk in hand and what is sampled. A forgotten time cannot be sampled again.
"""
from __future__ import annotations

import bisect
import contextlib
import math
from typing import Any

import numpy as np

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.motion.geometry import Program, Segment
from cnc_contour_control.motion.jerk_stream import Chunk, chunk_deviation_m, chunk_holds_s
from cnc_contour_control.motion.plan_arrays import (
    Phases,
    SpeedBands,
    banded_junction_speeds_m_s,
    banded_phases,
    look_ahead_caps_m_s,
)
from cnc_contour_control.motion.plan_blocks import PlanBlocks, StreamSettings
from cnc_contour_control.motion.plan_views import PlannedSegments, ShiftedColumn
from cnc_contour_control.motion.points import FloatArray

#: Fewest planned segments committed per chunk: a short window still plans in blocks worth a NumPy pass (at 1024
#: streaming costs what the whole plan does per segment, 256 took 1.5 times as much; bench ``blending``).
MIN_CHUNK_SEGMENTS = 1024
#: Phases behind the tool that :meth:`StreamPlan.forget_before` lets gather before it drops them.
FORGET_PHASES = 2048


class StreamPlan:
    """The phases of a program's feed profile, planned a chunk at a time as far as asked (:meth:`extend_to`).

    The lists ``start_s``, ``s0_m``, ``v0_m_s``, ``accel_m_s2``, ``segment`` (one entry per committed phase, as
    :class:`~cnc_contour_control.motion.plan_arrays.Phases` without the end time) and ``segments`` (the planned segments
    so far) only grow; ``planned_until_s`` is the end of the committed phases, ``finished`` whether that is the
    profile's end.
    """

    def __init__(self, program: Program, settings: StreamSettings, chunk_segments: int | None = None) -> None:
        self.settings = settings
        #: Planned segments committed per chunk (a planner process plans with its parent's).
        self.chunk_segments = self._chunk = (max(settings.look_ahead_segments, MIN_CHUNK_SEGMENTS)
                                             if chunk_segments is None else chunk_segments)
        self._blocks = PlanBlocks(program, settings, self._chunk)
        self.segments = PlannedSegments(self._blocks)
        self.start_s: list[float] = []
        self.s0_m: list[float] = []
        self.v0_m_s: list[float] = []
        self.accel_m_s2: list[float] = []
        self.segment: list[int] = []
        self.junction_speeds_m_s: list[float] = [0.0]
        self.planned_until_s = 0.0
        self.finished = False
        self._phases: Phases | None = None
        self._forgotten_junctions = 0
        #: Streamed fir: chunks planned again with smaller caps, and chunks still over P at the smallest (published).
        self.replanned_chunks, self.over_tolerance_chunks = 0, 0
        #: Streamed fir: the largest deviation (m) of a published chunk's filtered reference from the programmed path.
        self.worst_deviation_m = 0.0
        self._hold_first_s = 0.0  # the hold at the next chunk's first junction (after a chunk of stops)
        self._pending: Chunk | None = None  # fir: the chunk planned, published once the next one is checked
        #: Held while phases are published or forgotten (a :class:`~cnc_contour_control.motion.plan_background.
        #: BackgroundPlanner`'s condition once attached, which also hears of each chunk).
        self.guard: Any = contextlib.nullcontext()
        self.background: Any = None
        self._plan_chunk()

    @property
    def committed_segments(self) -> int:
        """Planned segments whose speeds and phases are committed."""
        return self._forgotten_junctions + len(self.junction_speeds_m_s) - 1

    def plan_chunk(self) -> None:
        """Commit the next chunk (a :class:`~cnc_contour_control.motion.plan_background.BackgroundPlanner`'s step)."""
        self._plan_chunk()

    def forget_before(self, t_s: float) -> None:
        """Drop the phases that end before ``t_s`` (s) and the planned segments before the first one kept, once
        ``FORGET_PHASES`` have gathered. Sampling before ``t_s`` afterwards is not supported (a forgotten segment raises
        :class:`ProgramError`), nor are the whole plan's arrays (:meth:`whole`)."""
        if self.settings.fir is not None:  # the next chunk's check reaches back one filter window
            t_s = min(t_s, self.planned_until_s - self.settings.fir.window_s)
        k = bisect.bisect_right(self.start_s, t_s) - 1
        if k < FORGET_PHASES:
            return
        for values in (self.start_s, self.s0_m, self.v0_m_s, self.accel_m_s2, self.segment):
            del values[:k]
        first = self.segment[0]
        drop = first - self._forgotten_junctions  # junction speeds before the first kept segment
        if drop > 0:
            del self.junction_speeds_m_s[:drop]
            self._forgotten_junctions += drop
        self._blocks.forget(first)
        self._phases = None

    def held_rows(self) -> int:
        """Entries the plan holds: phases, junction speeds, planned segments and their columns (flat when forgetting
        keeps pace with the tool)."""
        return 5 * len(self.start_s) + len(self.junction_speeds_m_s) + self._blocks.held_rows()

    def extend_to(self, t_s: float) -> float:
        """Plan until the committed phases reach past ``t_s`` (s) or the end; the duration if known, else inf."""
        if self.background is not None:  # planned in its thread: wait for it
            return float(self.background.wait_until(t_s))
        while not self.finished and self.planned_until_s <= t_s:
            self._plan_chunk()
        return self.planned_until_s if self.finished else math.inf

    def finish(self) -> float:
        """Plan to the end; the profile's duration, s."""
        return self.extend_to(math.inf)

    def _plan_chunk(self) -> None:
        """Commit the next chunk of planned segments: computed first, published under :attr:`guard` (fir: once the
        next one is planned and checked, :mod:`~cnc_contour_control.motion.jerk_stream`)."""
        if self.settings.fir is None:
            chunk = self._plan_fir_chunk(self.committed_segments, self.junction_speeds_m_s[-1], 0, False, 0.0)
            self._commit(chunk)
            return
        if self._pending is None:
            self._pending = self._plan_fir_chunk(self.committed_segments, self.junction_speeds_m_s[-1], 0, False,
                                                 self._hold_first_s)
        pending = self._pending
        if not pending.last:
            j, tolerance_m = pending.j + pending.commit, self.settings.path_tolerance_m
            after = self._plan_fir_chunk(j, float(pending.speeds[pending.commit]), 0, False, pending.hold_next_s,
                                         pending)
            if after.attempt or after.deviation_m > tolerance_m:  # its caps lowered: the seam a stop, held
                self.replanned_chunks += 1
                pending = self._plan_fir_chunk(pending.j, self.junction_speeds_m_s[-1], pending.attempt, True,
                                               pending.hold_first_s, only=True)
                after = self._plan_fir_chunk(j, 0.0, after.attempt, False, pending.hold_next_s, pending)
        self._commit(pending)
        self._pending = None if pending.last else after
        self._hold_first_s = pending.hold_next_s

    def receive(self, j: int, commit: int, speeds: FloatArray, last: bool, phases: Phases, segments: list[Segment],
                rows: dict[str, np.ndarray], total_m: float) -> None:
        """Commit the chunk another process planned from planned segment ``j`` (``commit`` segments, their ``rows``
        of every column, the junction ``speeds`` from ``j`` and the ``phases`` from 0, as :meth:`plan_chunk` would
        have committed it here): :mod:`~cnc_contour_control.motion.plan_process`."""
        with self.guard:
            if j != self.committed_segments:
                raise ProgramError(f"a chunk from planned segment {j} does not follow the {self.committed_segments} "
                                   "committed here")
            self._blocks.put(j, segments, rows, total_m)
            self._publish(j, commit, speeds, last, phases)

    def _plan_fir_chunk(self, j: int, entry_m_s: float, first_attempt: int, end_stop: bool, hold_first_s: float,
                        before: Chunk | None = None, only: bool = False) -> Chunk:
        """Plan the chunk from planned segment ``j`` at ``entry_m_s`` (after the unpublished ``before``); fir: from
        attempt ``first_attempt`` (``only``: that one, whose caps its entry speed was planned with) until within P
        (1: the smaller caps, 2: every junction a stop), ``end_stop``: at rest at its end, ``hold_first_s``: the
        hold at its first junction if at rest (s)."""
        chunk, window, blocks = self._chunk, self.settings.look_ahead_segments, self._blocks
        blocks.ensure(j + chunk + window + 1)
        total = blocks.count
        end = min(j + chunk + window, total)
        last = blocks.exhausted and end == total
        commit = end - j if last else chunk
        length = blocks.rows("length", j, end)
        fir, smaller = self.settings.fir, self.settings.fir_smaller
        start_s = self.planned_until_s if before is None else before.end_s
        kept = self.phases() if before is None else before.after(self.phases())
        deviation_m, attempt = 0.0, first_attempt
        for attempt in range(first_attempt, 1 if fir is None or smaller is None else first_attempt + 1 if only else 3):
            if attempt == 1 and smaller is not None:  # the chunk's arcs at the smaller caps (the window's as they were)
                blocks.recap(j, j + commit, smaller)
            cruise, bands = blocks.rows("cruise", j, end), SpeedBands(blocks.rows("edges", j, end),
                                                                       blocks.rows("accel", j, end))
            caps = look_ahead_caps_m_s(bands.accel_m_s2[:, -1], length, window)  # inf past J + C unless last
            caps[1:commit + 1] = 0.0 if attempt == 2 else caps[1:commit + 1]  # every junction a stop
            caps[commit] = 0.0 if end_stop else caps[commit]
            speeds = banded_junction_speeds_m_s(cruise, bands, length, blocks.rows("smooth", j, end - 1), caps,
                                                entry_m_s)
            phases = self._chunk_phases(j, commit, speeds, last, attempt == 2, hold_first_s)
            result = Chunk(j, commit, speeds, last, phases, attempt, deviation_m, start_s, hold_first_s,
                            fir.window_s if fir is not None and (attempt == 2 or end_stop) else 0.0)
            if fir is None:
                break
            sources = ShiftedColumn(blocks.column("source"), blocks.base)
            result.deviation_m = deviation_m = chunk_deviation_m(
                kept, self._global(phases, j, start_s), self.segments, sources, blocks.program, fir, last)
            if deviation_m <= self.settings.path_tolerance_m:
                break
        self.replanned_chunks += attempt - first_attempt
        return result

    def _global(self, phases: Phases, j: int, start_s: float) -> Phases:
        """A chunk's ``phases`` in profile time (from ``start_s``) and global segment indices."""
        return Phases(phases.start_s + start_s, phases.s0_m, phases.v0_m_s, phases.accel_m_s2, phases.segment + j)

    def _chunk_phases(self, j: int, commit: int, speeds: FloatArray, last: bool, stops: bool,
                      hold_first_s: float) -> Phases:
        """The phases of planned segments ``j .. j + commit - 1`` at junction ``speeds``; fir: stops held (with
        ``stops``, every stop of the chunk held the filter's window; ``hold_first_s`` at its first junction)."""
        blocks, fir = self._blocks, self.settings.fir
        dwell = np.append(blocks.rows("dwell", j, j + commit), blocks.end_dwell_s() if last else 0.0)
        if fir is not None:
            if speeds[0] <= 0.0:
                dwell[0] = max(dwell[0], hold_first_s)
            if stops:
                held = np.flatnonzero(speeds[:commit] <= 0.0)
                dwell[held] = np.maximum(dwell[held], fir.window_s)
            before = int(j > 0)
            segments = [self.segments[i] for i in range(j - before, j + commit)]
            holds = chunk_holds_s(segments, speeds[:commit + 1], blocks.rows("accel", j - before, j + commit)[:, -1],
                                  bool(before), self.settings.corner_rad, fir)
            dwell[:commit] = np.maximum(dwell[:commit], holds)
        bands = SpeedBands(blocks.rows("edges", j, j + commit), blocks.rows("accel", j, j + commit))
        return banded_phases(blocks.rows("length", j, j + commit), speeds[:commit], speeds[1:commit + 1],
                             blocks.rows("cruise", j, j + commit), bands, dwell)

    def _commit(self, chunk: Chunk) -> None:
        if self.settings.fir is not None:
            self.over_tolerance_chunks += int(chunk.deviation_m > self.settings.path_tolerance_m)
            self.worst_deviation_m = max(self.worst_deviation_m, chunk.deviation_m)
        with self.guard:
            self._publish(chunk.j, chunk.commit, chunk.speeds, chunk.last, chunk.phases)

    def _publish(self, j: int, commit: int, speeds: FloatArray, last: bool, phases: Phases) -> None:
        self.start_s.extend((phases.start_s[:-1] + self.planned_until_s).tolist())
        self.s0_m.extend(phases.s0_m.tolist())
        self.v0_m_s.extend(phases.v0_m_s.tolist())
        self.accel_m_s2.extend(phases.accel_m_s2.tolist())
        self.segment.extend((phases.segment + j).tolist())
        self.junction_speeds_m_s.extend(speeds[1:commit + 1].tolist())
        self.planned_until_s += float(phases.start_s[-1])
        self.finished = last
        self._phases = None
        if self.background is not None:
            self.guard.notify_all()

    @property
    def program(self) -> Program:
        """The program it plans (as programmed)."""
        return self._blocks.program

    @property
    def n_axes(self) -> int:
        """Number of axes."""
        return self._blocks.program.n_axes

    @property
    def segment_start_m(self) -> ShiftedColumn:
        """Path length at the start of every planned segment so far, m (as :attr:`Program.segment_start_m`; indexed
        by global segment index, int or int array)."""
        return ShiftedColumn(self._blocks.column("start"), self._blocks.base)

    @property
    def total_length_m(self) -> float:
        """Length of the planned segments so far, m (the program's once :attr:`finished`)."""
        return self._blocks.total_m

    def phases(self) -> Phases:
        """The committed phases kept as arrays (``start_s`` ends with :attr:`planned_until_s`)."""
        if self._phases is None:
            self._phases = Phases(np.array(self.start_s + [self.planned_until_s]), np.array(self.s0_m),
                                  np.array(self.v0_m_s), np.array(self.accel_m_s2),
                                  np.array(self.segment, dtype=np.intp))
        return self._phases

    def whole(self) -> dict[str, object]:
        """Plan to the end; the whole plan's arrays by :class:`Interpolator` attribute name.

        Raises
        ------
        ProgramError
            If :meth:`forget_before` has dropped its start.
        """
        if self._blocks.base or self._forgotten_junctions:
            raise ProgramError(f"the streamed plan forgot its first {self._blocks.base} planned segments (on line, "
                               "behind the tool): the whole plan's arrays are gone")
        self.finish()
        edges, accel = self._blocks.column("edges"), self._blocks.column("accel")
        last = self.segments[-1]
        return {"duration_s": self.planned_until_s, "_phases": self.phases(), "_end_point_m": last.point(last.length_m),
                "junction_speeds_m_s": np.array(self.junction_speeds_m_s),
                "cruise_speed_m_s": self._blocks.column("cruise"), "tangential_acceleration_m_s2": accel[:, -1],
                "speed_bands": SpeedBands(edges, accel)}
