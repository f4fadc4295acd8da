"""A streaming plan's store of planned segments: the program blended and limited a block at a time, with one
array per planned segment quantity (ROS-free; :mod:`~cnc_contour_control.motion.plan_stream` plans from it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.motion.blend_choice import CornerLimits
from cnc_contour_control.motion.blending import blend_program
from cnc_contour_control.motion.geometry import Dwell, Program, Segment
from cnc_contour_control.motion.jerk_fir import FirSettings, capped_program
from cnc_contour_control.motion.plan_arrays import SpeedBands, plan_banded_limits
from cnc_contour_control.motion.points import FloatArray
from cnc_contour_control.motion.segment_tangents import junction_turns_rad


@dataclass(frozen=True)
class StreamSettings:
    """What a stream plans with: axis limits (m/s, m/s², ``(n_axes,)``), the planner's options, the tolerances.

    ``n_bands`` is the width of every segment's :class:`SpeedBands` (the planner's ``arc_speed_bands`` with the
    combined budget, else 1), ``tolerance_m`` the blend tolerance, ``corner_rad`` the tangent-corner angle.
    """

    max_velocity_m_s: FloatArray
    max_acceleration_m_s2: FloatArray
    centripetal_fraction: float
    combined_budget: bool
    clamp_feed: bool
    n_bands: int
    look_ahead_segments: int
    tolerance_m: float
    corner_rad: float
    #: ``jerk_mode`` fir's filter and caps (:mod:`~cnc_contour_control.motion.jerk_stream`), else None;
    #: ``fir_smaller`` the caps of a chunk over ``path_tolerance_m`` (m, P) planned again.
    fir: FirSettings | None = None
    fir_smaller: FirSettings | None = None
    path_tolerance_m: float = 0.0

    @property
    def corner_limits(self) -> CornerLimits:
        """The limits with which blending chooses a blend or a stop per corner."""
        return CornerLimits(self.max_velocity_m_s, self.max_acceleration_m_s2, self.centripetal_fraction)


class PlanBlocks:
    """The planned program, blended and limited ``block`` programmed segments at a time as far as asked; per planned
    segment arrays."""

    def __init__(self, program: Program, settings: StreamSettings, block: int) -> None:
        self.program, self.settings, self._block = program, settings, block
        self.segments: list[Segment] = []
        self._next = 0  # programmed segments already turned into planned ones
        self.base = 0  # planned segments forgotten (global index of ``segments[0]`` and of each column's row 0)
        self._carry_dwell_s = 0.0
        self._columns: dict[str, np.ndarray] = {}
        self._sizes: dict[str, int] = {}
        self.total_m = 0.0  # length of the planned segments so far, m

    @property
    def exhausted(self) -> bool:
        """Whether every programmed segment has been planned."""
        return self._next >= len(self.program.segments)

    @property
    def count(self) -> int:
        """Planned segments so far, forgotten ones included."""
        return self.base + len(self.segments)

    def ensure(self, count: int) -> None:
        """Plan programmed segments until at least ``count`` planned ones exist or the program is exhausted."""
        while self.count < count and not self.exhausted:
            self._add(self._next, min(self._next + self._block, len(self.program.segments)))

    def _sub_program(self, first: int, stop: int) -> Program:
        program = self.program
        dwells = tuple(Dwell(d.before_segment - first, d.duration_s, d.source_line) for d in program.dwells
                       if first < d.before_segment < stop)
        return Program(program.name, program.axis_names, program.segments[first:stop], dwells,
                       program.path_tolerance_m)

    def _add(self, begin: int, end: int) -> None:
        """Plan the pieces of programmed segments ``begin .. end - 1``."""
        first, stop = max(begin - 2, 0), min(end + 1, len(self.program.segments))
        settings = self.settings
        blended = blend_program(self._sub_program(first, stop), settings.tolerance_m, settings.corner_rad,
                                settings.corner_limits)
        sources = np.asarray(blended.source_segment or range(len(blended.planned.segments)), dtype=np.intp) + first
        planned = blended.planned
        if settings.fir is not None:  # fir's arc caps (a written arc may take the whole P)
            planned = capped_program(planned, settings.fir, self._sub_program(first, stop))
        rows = np.flatnonzero((sources >= begin) & (sources < end))
        new = [planned.segments[i] for i in rows.tolist()]
        dwell = self._dwells(sources[rows], begin, end)
        self._append(new, dwell, sources[rows])
        self._next = end

    def _dwells(self, sources: np.ndarray, begin: int, end: int) -> FloatArray:
        """Dwell before each new planned segment, s: a programmed junction's goes to the first planned piece after
        it (the whole plan's ``first_after``); one after the block's last piece is carried to the next block."""
        programmed = self.program.junction_dwell_s
        dwell = np.zeros(len(sources) + 1)
        dwell[0] = self._carry_dwell_s
        for k in (np.flatnonzero(programmed[begin:end] > 0.0) + begin).tolist():
            dwell[int(np.searchsorted(sources, k))] += programmed[k]
        self._carry_dwell_s = float(dwell[-1]) + (float(programmed[-1]) if end == len(self.program.segments) else 0.0)
        return dwell[:-1]

    def _limits(self, new: list[Segment], start: int) -> tuple[FloatArray, SpeedBands]:
        s = self.settings
        speed, _, bands = plan_banded_limits(new, s.max_velocity_m_s, s.max_acceleration_m_s2,
                                             s.centripetal_fraction, s.combined_budget, s.clamp_feed, start,
                                             s.n_bands)
        if bands.n_bands != s.n_bands:
            bands = SpeedBands.single(speed, bands.accel_m_s2[:, -1], s.n_bands)
        return speed, bands

    def recap(self, first: int, stop: int, fir: FirSettings) -> None:
        """Cap the arcs of planned segments ``first .. stop - 1`` again with ``fir`` (a streamed fir chunk over P)
        and their limits' rows with them (an arc capped before is taken as a blend's: the smaller tolerance)."""
        kept = self.segments[first - self.base:stop - self.base]
        capped = capped_program(Program("chunk", self.program.axis_names, tuple(kept)), fir).segments
        if all(a is b for a, b in zip(capped, kept)):
            return
        self.segments[first - self.base:stop - self.base] = capped
        speed, bands = self._limits(list(capped), first)
        for name, value in (("cruise", speed), ("edges", bands.edges_m_s), ("accel", bands.accel_m_s2)):
            self._columns[name][first - self.base:stop - self.base] = value

    def _append(self, new: list[Segment], dwell: FloatArray, sources: np.ndarray) -> None:
        s = self.settings
        speed, bands = self._limits(new, self.count)
        turns = junction_turns_rad(self.segments[-1:] + new)  # the junctions before new[1:], or before new[0:]
        smooth = (turns <= s.corner_rad) & (dwell[len(dwell) - len(turns):] == 0.0)
        length = np.array([seg.length_m for seg in new])
        ends = np.cumsum(np.concatenate(([self.total_m], length)))  # sequential: the whole program's cumsum
        self.total_m = float(ends[-1])
        for name, value in (("length", length), ("start", ends[:-1]), ("cruise", speed), ("edges", bands.edges_m_s),
                            ("accel", bands.accel_m_s2), ("smooth", smooth), ("dwell", dwell),
                            ("source", sources)):
            self._grow(name, np.asarray(value))
        self.segments.extend(new)

    def _grow(self, name: str, rows: np.ndarray) -> None:
        """Append ``rows`` to column ``name`` (capacity doubled when full: amortised O(1) per row)."""
        size = self._sizes.get(name, 0)
        column = self._columns.get(name)
        if column is None or size + len(rows) > len(column):
            grown = np.empty((max(2 * (size + len(rows)), 1024),) + rows.shape[1:], dtype=rows.dtype)
            if column is not None:
                grown[:size] = column[:size]
            self._columns[name] = column = grown
        column[size:size + len(rows)] = rows
        self._sizes[name] = size + len(rows)

    def column(self, name: str) -> np.ndarray:
        """One per-segment array over the planned segments kept (from :attr:`base`), a view (``smooth``: per inner
        junction, row ``i`` the junction after segment ``base + i``)."""
        return self._columns[name][:self._sizes[name]]

    def rows(self, name: str, first: int, stop: int) -> np.ndarray:
        """Rows of column ``name`` for planned segments ``first .. stop - 1`` (global indices, not forgotten)."""
        return self._columns[name][first - self.base:stop - self.base]

    def forget(self, first: int) -> None:
        """Drop the planned segments before global index ``first`` and their rows."""
        n = min(first, self.count - 1) - self.base  # the last segment stays: the next block's junction needs it
        if n <= 0:
            return
        del self.segments[:n]
        for name, column in self._columns.items():
            size = self._sizes[name]
            column[:size - n] = column[n:size]
            self._sizes[name] = size - n
        self.base += n

    def export(self, first: int, stop: int) -> tuple[list[Segment], dict[str, np.ndarray]]:
        """Planned segments ``first .. stop - 1`` and copies of their rows of every column, for :meth:`put`."""
        rows = {name: self.rows(name, first, stop).copy() for name in self._columns}
        return self.segments[first - self.base:stop - self.base], rows

    def put(self, first: int, segments: list[Segment], rows: dict[str, np.ndarray], total_m: float) -> None:
        """Hold ``segments`` (with their ``rows`` of every column) from global index ``first``, as another process
        planned them, in place of what this one planned from there (a streamed fir chunk's arcs may have been capped
        again since); ``total_m`` is that process's planned length, m."""
        at = first - self.base
        if not 0 <= at <= len(self.segments):
            raise ProgramError(f"planned segments from {first} do not follow the {self.count} held here")
        del self.segments[at:]
        self.segments.extend(segments)
        for name, values in rows.items():
            self._sizes[name] = min(self._sizes.get(name, 0), at)
            self._grow(name, values)
        self.total_m = total_m

    def held_rows(self) -> int:
        """Rows held: planned segments kept plus the columns' capacity (what the plan's memory grows with)."""
        return len(self.segments) + sum(len(column) for column in self._columns.values())

    def end_dwell_s(self) -> float:
        """The dwell at the program's end, s (once exhausted)."""
        return self._carry_dwell_s
