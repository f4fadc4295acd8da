"""Corner blending within a path tolerance (G64 P): corners rounded by tangent arcs.

A line-line corner at point ``P`` between unit directions ``u1`` (in) and
``u2`` (out), turning by ``θ``, is replaced by the circular arc of radius ``R``
tangent to both lines at ``P - d u1`` and ``P + d u2``, with

    d = R tan(θ/2)                   (trim of each neighbour, m)
    e = R (1 - cos(θ/2))             (largest distance of the arc from the two lines, m)

``R`` is the largest radius with ``e <= tolerance`` and ``d <= length / 2`` of
both neighbours: the tolerance is measured to the programmed path (at the
arc's midpoint, the farthest point, which lies ``R (1/cos(θ/2) - 1)`` from
``P``), so a sharp corner gets the whole tolerance. A line-arc or arc-arc corner in one coordinate plane
gets the fillet circle tangent to both curves (:mod:`cnc_contour_control.motion.blend_fillet`), a line
leaving a planar arc's plane three arcs (:mod:`cnc_contour_control.motion.blend_ramp`),
their deviation measured exactly and kept within the tolerance. Given the planner's
limits (:class:`~cnc_contour_control.motion.blend_choice.CornerLimits`), a blend is kept only where it is
quicker than an exact stop (:func:`~cnc_contour_control.motion.blend_choice.faster_than_stop`). A corner is left
as it is (an exact stop for the planner, unless already tangent) when: a dwell
(G4) sits at the junction, the turn is below ``min_angle_rad`` or within 1e-6
rad of a reversal, the arc's chord would be under 2 µm (``2 POSITION_TOLERANCE_M``;
an arc with closer ends is a full circle), the two lines do not span one
coordinate plane (an :class:`ArcSegment` lies in one), or a helix, or a line moving two axes off the arc's
plane or none in it takes part. The blended program is a plain
:class:`Program`, so every consumer (planner, ``path`` topic) takes it as is.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.blend_assembly import planned_segments
from cnc_contour_control.motion.blend_choice import CornerLimits, faster_than_stop, quickest_radius, slower_arcs
from cnc_contour_control.motion.blend_fillet import lift, plan_fillet
from cnc_contour_control.motion.blend_ramp import plan_ramp
from cnc_contour_control.motion.blend_table import Blend, BlendTable, one_arc
from cnc_contour_control.motion.geometry import Dwell, LineSegment, Program, Segment
from cnc_contour_control.motion.points import POSITION_TOLERANCE_M, FloatArray, IntArray
from cnc_contour_control.motion.segment_tangents import junction_turns_rad

_AXIS_EPS = 1.0e-12
_REVERSAL_MARGIN_RAD = 1.0e-6
#: Shortest chord of a blend arc, m: an :class:`ArcSegment` whose ends are within
#: ``POSITION_TOLERANCE_M`` is a full circle, so smaller blends stay corners.
_MIN_CHORD_M = 2.0 * POSITION_TOLERANCE_M
#: The radii of a line-line corner's blend compared between cruising neighbours
#: (:func:`~cnc_contour_control.motion.blend_choice.quickest_radius`), as shares of the largest within the
#: tolerance, where the largest arc is slower than its lines (a shorter one can then be quicker, as where an
#: axis's velocity limit caps the arc and not the lines).
RADIUS_SCALES = (1.0, 0.5, 0.25, 0.125)
#: Shares of the tolerance a fillet search is tried at until one finds a fillet.
_FILLET_RETRY_SHARES = (1.0, 0.25, 0.0625, 0.015625)
#: Shares of the tolerance :func:`quickest_blend` tries when the blended plan is slower than exact stop.
_SMALLER_TOLERANCE_SHARES = (0.25, 0.0625)


@dataclass(frozen=True)
class BlendedProgram:
    """The programmed contour, the planned one (with blend arcs) and the blends.

    With no blend ``planned`` is ``programmed`` itself (same object).
    """

    programmed: Program
    planned: Program
    #: The blends as arrays, in junction order (:attr:`blends` as objects).
    table: BlendTable
    tolerance_m: float
    #: Per planned segment, the programmed segment it comes from (a blend arc: the one after its corner).
    source_segment: tuple[int, ...] = ()

    @classmethod
    def unblended(cls, program: Program, tolerance_m: float) -> BlendedProgram:
        """``program`` planned as written (exact stop at every corner) under ``tolerance_m``."""
        return cls(program, program, BlendTable.empty(program.n_axes), tolerance_m)

    @functools.cached_property
    def blends(self) -> tuple[Blend, ...]:
        """The blends, one :class:`Blend` per rounded corner, in junction order."""
        return self.table.rows()

    def deviation_m(self, points: ArrayLike) -> FloatArray:
        """Exact distance (m, shape ``(N,)``) of ``points`` (``(N, n_axes)``, m) from the programmed path."""
        return self.programmed.contour_distance(points)[0]

    def local_deviation_m(self, points: ArrayLike, planned_index: ArrayLike) -> FloatArray:
        """Exact distance (m, ``(N,)``) of each point from the programmed segments its planned segment comes from.

        A blend arc's point is measured to both segments of its corner, any other
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


def corner_trim_m(turn_rad: ArrayLike, tolerance_m: float, max_trim_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Radius (m) and trim (m) of the blends of corners turning by ``turn_rad`` (scalars or arrays of one shape).

    Parameters
    ----------
    turn_rad : float or ndarray
        Angle between the incoming and outgoing directions, rad, in (0, π).
    tolerance_m : float
        Largest distance of the arc from the two lines of the corner, m, > 0.
    max_trim_m : float or ndarray
        Largest length the blend may take from each neighbour, m.
    """
    half = 0.5 * np.asarray(turn_rad, dtype=float)
    radius = np.minimum(tolerance_m / (1.0 - np.cos(half)), np.asarray(max_trim_m) / np.tan(half))
    return radius, radius * np.tan(half)


def _line_corners(program: Program, junctions: IntArray, turns_rad: FloatArray, tolerance_m: float,
                  scale: float = 1.0) -> BlendTable:
    """The tangent arcs of the line-line corners before segments ``junctions`` (closed form, all at once).

    ``scale`` (in (0, 1]) shrinks each radius and trim from the largest within the tolerance. A corner whose
    lines move three or more axes, or whose arc's chord would be under 2 µm, is left out.
    """
    segments = program.segments
    u1 = np.array([segments[k - 1].unit_vector for k in junctions]).reshape(len(junctions), program.n_axes)
    u2 = np.array([segments[k].unit_vector for k in junctions]).reshape(u1.shape)
    shorter = np.minimum([segments[k - 1].length_m for k in junctions], [segments[k].length_m for k in junctions])
    radius, trim = (scale * value for value in corner_trim_m(turns_rad, tolerance_m, 0.5 * shorter))
    moving = (np.abs(u1) > _AXIS_EPS) | (np.abs(u2) > _AXIS_EPS)
    keep = np.flatnonzero((moving.sum(axis=1) == 2) & (2.0 * radius * np.sin(0.5 * turns_rad) > _MIN_CHORD_M))
    first = np.argmax(moving, axis=1)
    second = moving.shape[1] - 1 - np.argmax(moving[:, ::-1], axis=1)
    rows = np.arange(len(junctions))
    clockwise = u1[rows, first] * u2[rows, second] - u1[rows, second] * u2[rows, first] < 0.0
    normal = u2 - np.einsum("ij,ij->i", u1, u2)[:, None] * u1
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
    corner = np.array([segments[k].start_m for k in junctions]).reshape(u1.shape)
    start, end = corner - trim[:, None] * u1, corner + trim[:, None] * u2
    center, deviation = start + radius[:, None] * normal, radius * (1.0 - np.cos(0.5 * turns_rad))
    return BlendTable(junctions[keep], radius[keep], trim[keep], deviation[keep], trim[keep], start[keep], end[keep],
                      center[keep], np.c_[first, second][keep], clockwise[keep], one_arc(keep.size))


def _curve_corner(k: int, before: Segment, after: Segment, turn: float, tolerance_m: float) -> Blend | None:
    """The fillet of a line-arc or arc-arc corner (:func:`blend_fillet.plan_fillet`), or None.

    Where the search finds none within ``tolerance_m`` it tries a quarter of it, down to 1/64 (a smaller
    fillet may fit where the search from a large one ends without one).
    """
    planned = None
    for share in _FILLET_RETRY_SHARES:
        planned = plan_fillet(before, after, share * tolerance_m, turn)
        if planned is not None:
            break
    if planned is None:
        return _ramp_corner(k, before, after, tolerance_m)
    shape, corner = planned.shape, after.start_m
    if float(np.hypot(*(shape.end - shape.start))) <= _MIN_CHORD_M:
        return None
    return Blend(k, shape.radius_m, shape.trim_before_m, planned.deviation_m, shape.trim_after_m,
                 lift(shape.start, planned.plane, corner), lift(shape.end, planned.plane, corner),
                 lift(shape.center, planned.plane, corner), planned.plane, planned.side < 0.0)


def _ramp_corner(k: int, before: Segment, after: Segment, tolerance_m: float) -> Blend | None:
    """The blend of pieces of a 3-axis line-arc corner (:func:`blend_ramp.plan_ramp`), or None."""
    ramp = plan_ramp(before, after, tolerance_m)
    if ramp is None:
        return None
    last = ramp.pieces[-1]
    return Blend(k, ramp.radius_m, ramp.trim_before_m, ramp.deviation_m, ramp.trim_after_m, ramp.pieces[0].start_m,
                 last.end_m, last.center_m, last.plane, last.clockwise, ramp.pieces)


def _plan_corners(program: Program, tolerance_m: float, min_angle_rad: float,
                  limits: CornerLimits | None) -> BlendTable:
    """The blends of every corner that gets one (with ``limits``: only where quicker than a stop), in junction order."""
    segments = program.segments
    turns = junction_turns_rad(segments)
    lines = np.array([isinstance(segment, LineSegment) for segment in segments])
    free = program.junction_dwell_s[1:-1] == 0.0
    corner = (turns > min_angle_rad) & (turns < math.pi - _REVERSAL_MARGIN_RAD) & free
    line_pair = corner & lines[:-1] & lines[1:]
    by_line = np.flatnonzero(line_pair)
    curved = np.flatnonzero(corner & ~line_pair) + 1
    line_table = BlendTable.empty(program.n_axes)
    if by_line.size:
        line_table = _line_corners(program, by_line + 1, turns[by_line], tolerance_m)
    if limits is not None and len(line_table):
        line_table = _line_radii(program, line_table, turns, tolerance_m, limits)
    table = line_table.merged(_curve_corners(program, curved, turns, tolerance_m))
    return table if limits is None else table.subset(faster_than_stop(segments, table, limits))


def _line_radii(program: Program, largest: BlendTable, turns_rad: FloatArray, tolerance_m: float,
                limits: CornerLimits) -> BlendTable:
    """``largest`` with each blend whose arc is slower than its lines replaced by the quickest of
    :data:`RADIUS_SCALES` (:func:`~cnc_contour_control.motion.blend_choice.quickest_radius`)."""
    capped = slower_arcs(program.segments, largest, limits)
    if not capped.any():
        return largest
    junctions = largest.junction[capped]
    candidates = [largest.subset(capped)] + [_line_corners(program, junctions, turns_rad[junctions - 1], tolerance_m,
                                                           scale) for scale in RADIUS_SCALES[1:]]
    return largest.subset(~capped).merged(quickest_radius(program.segments, candidates, limits))


def _curve_corners(program: Program, junctions: IntArray, turns_rad: FloatArray, tolerance_m: float) -> BlendTable:
    """The fillets of the line-arc and arc-arc corners before segments ``junctions`` that get one."""
    segments = program.segments
    curves = [_curve_corner(k, segments[k - 1], segments[k], float(turns_rad[k - 1]), tolerance_m)
              for k in junctions.tolist()]
    return BlendTable.from_blends([b for b in curves if b is not None], program.n_axes)


def blend_program(program: Program, tolerance_m: float, min_angle_rad: float = 0.0,
                  limits: CornerLimits | None = None) -> BlendedProgram:
    """Round every blendable corner of ``program`` within ``tolerance_m`` (m, >= 0).

    Parameters
    ----------
    program : Program
        The programmed contour.
    tolerance_m : float
        Path tolerance, m; 0 leaves the program unchanged.
    min_angle_rad : float
        Corners turning by at most this angle (rad) are passed as tangent and not blended.
    limits : CornerLimits, optional
        The planner's limits: a corner keeps its blend only where that is quicker than an exact stop
        (:func:`~cnc_contour_control.motion.blend_choice.faster_than_stop`). None: every blend is kept.

    Returns
    -------
    BlendedProgram
        ``planned`` has the blend arcs; its dwells are moved to the same junctions.
    """
    if not (math.isfinite(tolerance_m) and tolerance_m >= 0.0):
        raise ConfigError(f"path tolerance_m must be finite and >= 0, got {tolerance_m}")
    if tolerance_m == 0.0:
        return BlendedProgram.unblended(program, 0.0)
    blends = _plan_corners(program, tolerance_m, min_angle_rad, limits)
    if not len(blends):
        return BlendedProgram(program, program, blends, tolerance_m)
    segments, first_after, sources = planned_segments(program, blends)
    first_after.append(len(segments))
    dwells = tuple(Dwell(first_after[d.before_segment], d.duration_s, d.source_line) for d in program.dwells)
    planned = Program(program.name, program.axis_names, tuple(segments), dwells, program.path_tolerance_m)
    return BlendedProgram(program, planned, blends, tolerance_m, tuple(sources))


def quickest_blend(program: Program, tolerance_m: float, min_angle_rad: float, limits: CornerLimits,
                   duration_s: Callable[[Program], float]) -> BlendedProgram:
    """:func:`blend_program` whose plan is never slower than exact stop (``duration_s``: a planned program's time).

    The per-corner choice judges each corner alone. Where the blended plan is slower than the program as
    written, the blends within a quarter and a sixteenth of the tolerance are tried (a smaller arc can be
    quicker where the path speeds up or turns sharply); the quickest plan is kept, exact stop if none beats it.
    The result's ``tolerance_m`` is ``tolerance_m`` whichever was kept.
    """
    best = blend_program(program, tolerance_m, min_angle_rad, limits)
    best_s = duration_s(best.planned)
    if not len(best.table):
        return best
    stop_s = duration_s(program)
    if best_s <= stop_s:
        return best
    for share in _SMALLER_TOLERANCE_SHARES:
        smaller = blend_program(program, share * tolerance_m, min_angle_rad, limits)
        if len(smaller.table) and (smaller_s := duration_s(smaller.planned)) < best_s:
            best, best_s = dataclasses.replace(smaller, tolerance_m=tolerance_m), smaller_s
    return best if best_s < stop_s else BlendedProgram.unblended(program, tolerance_m)
