"""Contour geometry: line and arc segments and the program they form.

Every array is SI (m) with one entry per machine axis, in the order of the
program's ``axis_names``. Segments are parameterised by their arc length
``s_m`` in ``[0, length_m]``; evaluations outside that range are clamped.
Point-like methods accept a scalar ``s_m`` (result shape ``(n_axes,)``) or
an array of shape ``(M,)`` (result shape ``(M, n_axes)``).

Lines and the program live here; arcs in :mod:`cnc_contour_control.motion.arc`; what
both share (point arrays, tolerances) in :mod:`cnc_contour_control.motion.points`.
Everything is importable from here as before.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.points import (
    MIN_LENGTH_M,
    POSITION_TOLERANCE_M,
    FloatArray,
    IntArray,
    as_point,
    as_points,
    require_feed,
)
from cnc_contour_control.motion.segment_boxes import SegmentBoxes

#: Programs with at least this many segments find a point's nearest segment through :class:`SegmentBoxes`.
PREFILTER_MIN_SEGMENTS = 256

__all__ = ["ArcSegment", "Dwell", "FloatArray", "IntArray", "LineSegment", "MIN_LENGTH_M", "POSITION_TOLERANCE_M",
           "Program", "Segment", "as_point", "as_points", "segment_label"]


@dataclass(frozen=True, eq=False)
class LineSegment:
    """A straight segment from ``start_m`` to ``end_m`` at feed ``feed_m_s``.

    Parameters
    ----------
    start_m, end_m : array_like, shape (n_axes,)
        End points, m.
    feed_m_s : float
        Programmed feed (path speed), m/s, > 0.
    source_line : int, optional
        Line of the source text (G-code) the segment comes from, for messages.
    """

    start_m: FloatArray
    end_m: FloatArray
    feed_m_s: float
    #: Line of the source text (G-code) the segment comes from, 1-based; None if none.
    source_line: int | None = None
    length_m: float = field(init=False)
    #: Unit direction of travel, shape ``(n_axes,)``.
    unit_vector: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        start = as_point("start_m", self.start_m)
        end = as_point("end_m", self.end_m, start.size)
        delta = end - start
        length = float(np.linalg.norm(delta))
        if length < MIN_LENGTH_M:
            raise ProgramError(f"line length_m must be >= {MIN_LENGTH_M}, got {length} (start_m == end_m)")
        unit = delta / length
        unit.setflags(write=False)
        for name, value in (("start_m", start), ("end_m", end), ("length_m", length), ("unit_vector", unit)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "feed_m_s", require_feed(self.feed_m_s))

    @classmethod
    def from_validated(cls, start_m: FloatArray, end_m: FloatArray, feed_m_s: float, source_line: int | None,
                       length_m: float, unit_vector: FloatArray) -> LineSegment:
        """A segment from values a batch builder has validated and derived (read-only arrays), without re-checking.

        :func:`cnc_contour_control.motion.segment_batch.line_segments` is the one caller; it checks what
        ``__post_init__`` checks, for many segments at once.
        """
        segment = object.__new__(cls)
        segment.__dict__.update(start_m=start_m, end_m=end_m, feed_m_s=feed_m_s, source_line=source_line,
                                length_m=length_m, unit_vector=unit_vector)  # as object.__setattr__ per field
        return segment

    @property
    def n_axes(self) -> int:
        """Number of axes."""
        return int(self.start_m.size)

    def point(self, s_m: ArrayLike) -> FloatArray:
        """Position at arc length ``s_m``, m; shape ``(n_axes,)`` or ``(M, n_axes)``."""
        s = np.clip(np.asarray(s_m, dtype=float), 0.0, self.length_m)
        return self.start_m + s[..., None] * self.unit_vector

    def tangent(self, s_m: ArrayLike) -> FloatArray:
        """Unit tangent (direction of travel) at ``s_m``; shape as :meth:`point`."""
        shape = np.shape(s_m) + (self.n_axes,)
        return np.broadcast_to(self.unit_vector, shape).copy()

    def curvature_vector(self, s_m: ArrayLike) -> FloatArray:
        """Curvature vector, 1/m: zero for a line; shape as :meth:`point`."""
        return np.zeros(np.shape(s_m) + (self.n_axes,))

    def frame(self, s_m: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Point (m), unit tangent and curvature vector (1/m) at a scalar ``s_m``."""
        s = min(max(s_m, 0.0), self.length_m)
        return self.start_m + s * self.unit_vector, self.unit_vector, np.zeros(self.n_axes)

    def max_abs_tangent(self) -> FloatArray:
        """Largest ``|tangent_j|`` over the segment per axis, shape ``(n_axes,)``."""
        return np.abs(self.unit_vector)

    def max_abs_curvature_per_m(self) -> FloatArray:
        """Largest ``|curvature_vector_j|`` over the segment per axis, 1/m: zeros."""
        return np.zeros(self.n_axes)

    def bounding_box_m(self) -> tuple[FloatArray, FloatArray]:
        """Lower and upper corners of a box containing the segment, m, each ``(n_axes,)``."""
        return np.minimum(self.start_m, self.end_m), np.maximum(self.start_m, self.end_m)

    def nearest(self, points: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Exact distance from each point to the segment and where it is reached.

        Parameters
        ----------
        points : array_like, shape (N, n_axes)
            Positions, m.

        Returns
        -------
        distance_m, s_m : ndarray, shape (N,)
            Distance to the nearest point of the segment (m) and its arc length (m).
        """
        relative = as_points(points, self.n_axes) - self.start_m
        s = np.clip(relative @ self.unit_vector, 0.0, self.length_m)
        distance = np.linalg.norm(relative - s[:, None] * self.unit_vector, axis=1)
        return distance, s


Segment = LineSegment | ArcSegment


def segment_label(index: int, segment: Segment) -> str:
    """How messages name a segment: ``"line 7 (segment 3)"`` when its source line is known, else ``"segment 3"``."""
    line = getattr(segment, "source_line", None)
    return f"segment {index}" if line is None else f"line {line} (segment {index})"


@dataclass(frozen=True)
class Dwell:
    """A stop of ``duration_s`` (s, >= 0) at the junction before segment ``before_segment``.

    ``before_segment`` is in ``[0, n_segments]``; ``n_segments`` is the
    program's end. ``source_line`` is the G-code line (G4) it comes from.
    """

    before_segment: int
    duration_s: float
    source_line: int | None = None


@dataclass(frozen=True, eq=False)
class Program:
    """A contiguous contour: segments in program order over named axes.

    Parameters
    ----------
    name : str
        Program or scenario name.
    axis_names : sequence of str
        Axis order of every segment's arrays, e.g. ``("x", "y")``.
    segments : sequence of LineSegment or ArcSegment
        Non-empty; each starts where the previous one ends (within ``POSITION_TOLERANCE_M``).
    dwells : sequence of Dwell, optional
        Stops held at junctions (G4); the interpolator halts there for their time.
    path_tolerance_m : float, optional
        Largest deviation from the programmed path a blending interpolator may
        take at junctions, m, >= 0 (``G64 P``); 0 is exact stop (``G61``);
        None leaves it to the interpolator's configuration.
    """

    name: str
    axis_names: tuple[str, ...]
    segments: tuple[Segment, ...]
    dwells: tuple[Dwell, ...] = ()
    path_tolerance_m: float | None = None
    segment_start_m: FloatArray = field(init=False, repr=False)
    total_length_m: float = field(init=False)
    #: Dwell time summed per junction, s, shape ``(n_segments + 1,)`` (index k: before segment k).
    junction_dwell_s: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        axes = tuple(self.axis_names)
        if not axes or len(set(axes)) != len(axes) or not all(isinstance(n, str) and n for n in axes):
            raise ProgramError(f"axis_names must be distinct non-empty names, got {list(axes)}")
        segments = tuple(self.segments)
        if not segments:
            raise ProgramError(f"program {self.name!r} has no segments")
        _check_segments(segments, axes)
        lengths = np.array([segment.length_m for segment in segments])
        starts = np.concatenate(([0.0], np.cumsum(lengths)[:-1]))
        starts.setflags(write=False)
        object.__setattr__(self, "axis_names", axes)
        object.__setattr__(self, "segments", segments)
        object.__setattr__(self, "segment_start_m", starts)
        object.__setattr__(self, "total_length_m", float(np.sum(lengths)))
        object.__setattr__(self, "dwells", tuple(self.dwells))
        object.__setattr__(self, "junction_dwell_s", _junction_dwells(self.dwells, len(segments)))
        if self.path_tolerance_m is not None and not (math.isfinite(self.path_tolerance_m)
                                                      and self.path_tolerance_m >= 0.0):
            raise ProgramError(f"path_tolerance_m must be finite and >= 0, got {self.path_tolerance_m}")

    @property
    def n_axes(self) -> int:
        """Number of axes."""
        return len(self.axis_names)

    @property
    def start_m(self) -> FloatArray:
        """Start point of the program, m, shape ``(n_axes,)``."""
        return self.segments[0].start_m

    @property
    def end_m(self) -> FloatArray:
        """End point of the program, m, shape ``(n_axes,)``."""
        return self.segments[-1].end_m

    def segment_boxes(self) -> SegmentBoxes:
        """Every segment's bounding box and end as arrays (built once, on first use; thread-safe to build early)."""
        boxes = self.__dict__.get("_segment_boxes")
        if boxes is None:
            boxes = SegmentBoxes.of(self.segments)
            object.__setattr__(self, "_segment_boxes", boxes)
        return boxes

    def contour_distance(self, points: ArrayLike) -> tuple[FloatArray, IntArray]:
        """Exact distance from each point to the whole contour.

        Segments whose bounding box is farther than the best distance found so
        far are skipped for that point; from :data:`PREFILTER_MIN_SEGMENTS` on,
        only the segments :meth:`SegmentBoxes.candidates` keeps are visited
        (the same result, without a Python loop over every segment).

        Parameters
        ----------
        points : array_like, shape (N, n_axes)
            Positions, m.

        Returns
        -------
        distance_m : ndarray, shape (N,)
            Distance to the nearest point of the contour, m.
        segment_index : ndarray of int, shape (N,)
            Index of the segment holding that point (the first one on ties).
        """
        p = as_points(points, self.n_axes)
        best = np.full(p.shape[0], np.inf)
        index = np.zeros(p.shape[0], dtype=np.intp)
        visit = range(len(self.segments)) if len(self.segments) < PREFILTER_MIN_SEGMENTS \
            else self.segment_boxes().candidates(p).tolist()
        for i in visit:
            segment = self.segments[i]
            low, high = segment.bounding_box_m()
            gap = np.maximum(np.maximum(low - p, p - high), 0.0)
            candidates = np.flatnonzero(np.einsum("ij,ij->i", gap, gap) < best * best)
            if candidates.size == 0:
                continue
            distance, _ = segment.nearest(p[candidates])
            better = distance < best[candidates]
            best[candidates[better]] = distance[better]
            index[candidates[better]] = i
        return best, index


def _junction_dwells(dwells: tuple[Dwell, ...], n_segments: int) -> FloatArray:
    """Dwell time per junction, s, shape ``(n_segments + 1,)``; refuses a dwell off the program."""
    times = np.zeros(n_segments + 1)
    for dwell in dwells:
        if not isinstance(dwell, Dwell) or not 0 <= dwell.before_segment <= n_segments:
            raise ProgramError(f"dwells must be Dwell with before_segment in [0, {n_segments}], got {dwell!r}")
        if not (math.isfinite(dwell.duration_s) and dwell.duration_s >= 0.0):
            raise ProgramError(f"dwell duration_s must be finite and >= 0, got {dwell.duration_s}")
        times[dwell.before_segment] += dwell.duration_s
    times.setflags(write=False)
    return times


def _check_segments(segments: tuple[Segment, ...], axes: tuple[str, ...]) -> None:
    """:func:`_check_segment` on every segment, the contiguity gaps of all segments in one NumPy pass.

    The first failing segment raises :func:`_check_segment`'s error, as a loop over them would.
    """
    kinds = (LineSegment, ArcSegment)
    valid = next((i for i, s in enumerate(segments) if not (isinstance(s, kinds) and s.n_axes == len(axes))),
                 len(segments))
    if valid > 1:
        ends = np.array([segment.end_m for segment in segments[:valid - 1]])
        starts = np.array([segment.start_m for segment in segments[1:valid]])
        gaps = np.flatnonzero(np.sqrt(np.einsum("ij,ij->i", starts - ends, starts - ends)) > POSITION_TOLERANCE_M)
        if gaps.size:
            _check_segment(int(gaps[0]) + 1, segments[gaps[0] + 1], axes, segments[gaps[0]])
    if valid < len(segments):
        _check_segment(valid, segments[valid], axes, segments[valid - 1] if valid else None)


def _check_segment(index: int, segment: Segment, axes: tuple[str, ...], previous: Segment | None) -> None:
    """Refuse a segment of the wrong kind or size, or one not starting where ``previous`` ends."""
    if not isinstance(segment, (LineSegment, ArcSegment)):
        raise ProgramError(f"segment {index}: must be a LineSegment or ArcSegment, got {type(segment).__name__}")
    if segment.n_axes != len(axes):
        raise ProgramError(f"segment {index}: has {segment.n_axes} axes, the program has {len(axes)} {list(axes)}")
    if previous is None:
        return
    gap = float(np.linalg.norm(segment.start_m - previous.end_m))
    if gap > POSITION_TOLERANCE_M:
        raise ProgramError(
            f"segment {index}: start_m {segment.start_m.tolist()} is {gap:.3g} m from the end of "
            f"segment {index - 1} {previous.end_m.tolist()}; contiguity tolerance is {POSITION_TOLERANCE_M} m")
