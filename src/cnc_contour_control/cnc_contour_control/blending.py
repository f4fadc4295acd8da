"""Corner blending within a path tolerance (G64 P): line-line corners rounded by tangent arcs.

A corner at point ``P`` between unit directions ``u1`` (in) and ``u2`` (out),
turning by ``θ``, is replaced by the circular arc of radius ``R`` tangent to
both lines at ``P - d u1`` and ``P + d u2``, with

    d = R tan(θ/2)                   (trim of each neighbour, m)
    e = R (1/cos(θ/2) - 1)           (distance from P to the arc's midpoint, m)

``R`` is the largest radius with ``e <= tolerance`` and ``d <= length / 2`` of
both neighbours. ``e`` bounds the arc's distance from the programmed path
(which is ``R (1 - cos(θ/2)) <= e``), so the planned path stays within the
tolerance everywhere. A corner is left as it is (an exact stop for the
planner, unless already tangent) when: a neighbour is an arc, a dwell (G4)
sits at the junction, the turn is below ``min_angle_rad`` or within 1e-6 rad
of a reversal, the arc's chord would be under 2 µm (``2 POSITION_TOLERANCE_M``;
an arc with closer ends is a full circle), or the two lines do not span one coordinate plane (an
:class:`ArcSegment` lies in one). The blended program is a plain
:class:`Program`, so every consumer (planner, ``path`` topic) takes it as is.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cnc_contour_control.arc import ArcSegment
from cnc_contour_control.errors import ConfigError
from cnc_contour_control.geometry import Dwell, LineSegment, Program, Segment
from cnc_contour_control.points import MIN_LENGTH_M, POSITION_TOLERANCE_M, FloatArray

_AXIS_EPS = 1.0e-12
_REVERSAL_MARGIN_RAD = 1.0e-6
#: Shortest chord of a blend arc, m: an :class:`ArcSegment` whose ends are within
#: ``POSITION_TOLERANCE_M`` is a full circle, so smaller blends stay corners.
_MIN_CHORD_M = 2.0 * POSITION_TOLERANCE_M


@dataclass(frozen=True)
class Blend:
    """One rounded corner: at the junction before programmed segment ``junction``.

    ``radius_m`` is the arc radius (m), ``trim_m`` the length taken from each
    neighbour (m), ``deviation_m`` the arc's largest distance from the corner
    point (m, <= the tolerance).
    """

    junction: int
    radius_m: float
    trim_m: float
    deviation_m: float


@dataclass(frozen=True)
class BlendedProgram:
    """The programmed contour, the planned one (with blend arcs) and the blends.

    With no blend ``planned`` is ``programmed`` itself (same object).
    """

    programmed: Program
    planned: Program
    blends: tuple[Blend, ...]
    tolerance_m: float
    #: Per planned segment, the programmed segment it comes from (a blend arc: the one after its corner).
    source_segment: tuple[int, ...] = ()

    def deviation_m(self, points: ArrayLike) -> FloatArray:
        """Exact distance (m, shape ``(N,)``) of ``points`` (``(N, n_axes)``, m) from the programmed path."""
        return self.programmed.contour_distance(points)[0]

    def local_deviation_m(self, points: ArrayLike, planned_index: ArrayLike) -> FloatArray:
        """Exact distance (m, ``(N,)``) of each point from the programmed segments its planned segment comes from.

        A blend arc's point is measured to both lines of its corner, any other
        point to its own programmed segment. It bounds :meth:`deviation_m` from
        above in one pass over the samples (for long programs).
        """
        p = np.asarray(points, dtype=float)
        index = np.asarray(planned_index, dtype=np.intp)
        sources = np.asarray(self.source_segment or range(len(self.planned.segments)), dtype=np.intp)
        out = np.full(len(p), np.inf)
        for k in np.unique(index):
            rows = np.flatnonzero(index == k)
            source = int(sources[k])
            around = (source - 1, source) if self.planned.segments[k] is not self.programmed.segments[source] \
                and isinstance(self.planned.segments[k], ArcSegment) else (source,)
            for j in around:
                out[rows] = np.minimum(out[rows], self.programmed.segments[j].nearest(p[rows])[0])
        return out


def _corner_plane(u1: FloatArray, u2: FloatArray) -> tuple[int, int] | None:
    """The coordinate plane spanned by both directions, or None if they need three axes or one."""
    moving = np.flatnonzero((np.abs(u1) > _AXIS_EPS) | (np.abs(u2) > _AXIS_EPS))
    return (int(moving[0]), int(moving[1])) if moving.size == 2 else None


def corner_trim_m(turn_rad: float, tolerance_m: float, max_trim_m: float) -> tuple[float, float]:
    """Radius (m) and trim (m) of the blend of a corner turning by ``turn_rad``.

    Parameters
    ----------
    turn_rad : float
        Angle between the incoming and outgoing directions, rad, in (0, π).
    tolerance_m : float
        Largest distance of the arc from the corner point, m, > 0.
    max_trim_m : float
        Largest length the blend may take from each neighbour, m.
    """
    half = 0.5 * turn_rad
    radius = tolerance_m / (1.0 / math.cos(half) - 1.0)
    radius = min(radius, max_trim_m / math.tan(half))
    return radius, radius * math.tan(half)


def _line_pair(program: Program, k: int) -> tuple[LineSegment, LineSegment] | None:
    before, after = program.segments[k - 1], program.segments[k]
    if not (isinstance(before, LineSegment) and isinstance(after, LineSegment)) or program.junction_dwell_s[k]:
        return None
    return before, after


def _plan_corner(program: Program, k: int, tolerance_m: float, min_angle_rad: float) -> Blend | None:
    """The blend of the junction before segment ``k``, or None if it stays a corner."""
    pair = _line_pair(program, k)
    if pair is None:
        return None
    before, after = pair
    turn = math.acos(min(1.0, max(-1.0, float(np.dot(before.unit_vector, after.unit_vector)))))
    if turn <= min_angle_rad or turn >= math.pi - _REVERSAL_MARGIN_RAD:
        return None
    if _corner_plane(before.unit_vector, after.unit_vector) is None:
        return None
    radius, trim = corner_trim_m(turn, tolerance_m, 0.5 * min(before.length_m, after.length_m))
    if 2.0 * radius * math.sin(0.5 * turn) <= _MIN_CHORD_M:
        return None
    return Blend(k, radius, trim, radius * (1.0 / math.cos(0.5 * turn) - 1.0))


def _arc(before: LineSegment, after: LineSegment, blend: Blend, start_m: FloatArray) -> ArcSegment:
    """The blend arc from ``start_m`` (on ``before``) to its tangent point on ``after``."""
    u1, u2 = before.unit_vector, after.unit_vector
    plane = _corner_plane(u1, u2)
    assert plane is not None
    normal = u2 - float(np.dot(u1, u2)) * u1
    center = start_m + blend.radius_m * normal / float(np.linalg.norm(normal))
    end = after.start_m + blend.trim_m * u2
    a, b = plane
    clockwise = u1[a] * u2[b] - u1[b] * u2[a] < 0.0
    return ArcSegment(start_m, end, center, bool(clockwise), plane, min(before.feed_m_s, after.feed_m_s),
                      after.source_line)


def _planned_segments(program: Program, trims: dict[int, Blend]) -> tuple[list[Segment], list[int], list[int]]:
    """Planned segments, per programmed junction the planned index after it, per planned segment its source."""
    out: list[Segment] = []
    first_after: list[int] = []
    sources: list[int] = []
    start = program.segments[0].start_m
    for k, segment in enumerate(program.segments):
        blend = trims.get(k)
        if blend is not None:
            previous = program.segments[k - 1]
            assert isinstance(previous, LineSegment) and isinstance(segment, LineSegment)
            out.append(_arc(previous, segment, blend, start))
            start = out[-1].end_m
        first_after.append(len(out))
        end_trim = trims[k + 1].trim_m if k + 1 in trims else 0.0
        out.extend(_trimmed(segment, start if blend is not None else None, end_trim))
        sources.extend([k] * (len(out) - len(sources)))
        start = out[-1].end_m if out else start
    return out, first_after, sources


def _trimmed(segment: Segment, start_m: FloatArray | None, end_trim_m: float) -> list[Segment]:
    """``segment`` from ``start_m`` (None: its own start) to ``end_trim_m`` (m) before its end.

    An untouched segment is returned itself; a remainder shorter than ``MIN_LENGTH_M`` (or reversed by rounding
    when two blends take half each) is dropped, the next blend starting where the previous one ends.
    """
    if isinstance(segment, ArcSegment) or (start_m is None and end_trim_m == 0.0):
        return [segment]
    start = segment.start_m if start_m is None else start_m
    end = segment.end_m - end_trim_m * segment.unit_vector if end_trim_m > 0.0 else segment.end_m
    if float(np.linalg.norm(end - start)) < MIN_LENGTH_M or float(np.dot(end - start, segment.unit_vector)) <= 0.0:
        return []
    return [LineSegment(start, end, segment.feed_m_s, segment.source_line)]


def blend_program(program: Program, tolerance_m: float, min_angle_rad: float = 0.0) -> BlendedProgram:
    """Round every blendable line-line corner of ``program`` within ``tolerance_m`` (m, >= 0).

    Parameters
    ----------
    program : Program
        The programmed contour.
    tolerance_m : float
        Path tolerance, m; 0 leaves the program unchanged.
    min_angle_rad : float
        Corners turning by at most this angle (rad) are passed as tangent and not blended.

    Returns
    -------
    BlendedProgram
        ``planned`` has the blend arcs; its dwells are moved to the same junctions.
    """
    if not (math.isfinite(tolerance_m) and tolerance_m >= 0.0):
        raise ConfigError(f"path tolerance_m must be finite and >= 0, got {tolerance_m}")
    if tolerance_m == 0.0:
        return BlendedProgram(program, program, (), 0.0)
    blends = [b for k in range(1, len(program.segments))
              if (b := _plan_corner(program, k, tolerance_m, min_angle_rad)) is not None]
    if not blends:
        return BlendedProgram(program, program, (), tolerance_m)
    segments, first_after, sources = _planned_segments(program, {b.junction: b for b in blends})
    first_after.append(len(segments))
    dwells = tuple(Dwell(first_after[d.before_segment], d.duration_s, d.source_line) for d in program.dwells)
    planned = Program(program.name, program.axis_names, tuple(segments), dwells, program.path_tolerance_m)
    return BlendedProgram(program, planned, tuple(blends), tolerance_m, tuple(sources))
