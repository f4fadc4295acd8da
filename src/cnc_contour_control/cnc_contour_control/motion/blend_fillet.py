"""Fillets of line-arc and arc-arc corners: the circle tangent to both curves, within a path tolerance.

At a corner ``P`` turning left (``side`` +1) or right (-1) by ``θ`` between a
segment ending at ``P`` and one starting there, both in one coordinate plane,
the fillet of radius ``r`` is centred where the two curves, offset by ``r``
toward the inside of the turn, meet:

    line  A + t u          offset  A + side r n          (n: left normal of u)
    arc   |q - O| = R      offset  |q - O| = R - dir side r   (dir +1 CCW)

Its tangent points ``T1``, ``T2`` are the centre's feet on the curves; the
fillet runs from ``T1`` to ``T2`` in the turn's direction, tangent to both. Its
deviation from the programmed path is measured, not bounded: the largest over
the fillet of the smaller exact distance to the two segments. Along the fillet
the distance to the first segment grows from 0 at ``T1`` and the distance to the
second falls to 0 at ``T2``, so the largest is where they cross: found on a grid
of the fillet angle (:class:`Piece`: closed-form distances in the plane) and
refined with :func:`scipy.optimize.brentq` on their difference; a grid maximum
away from the crossing is refined with :func:`scipy.optimize.minimize_scalar`.
:func:`deviation_m` measures the same with ``Segment.nearest`` (the reference,
~30× slower). The radius is the largest found (secant
steps on ``r``, deviation nearly proportional to it) whose deviation is at most
the tolerance and whose trims stay within each neighbour's share. Helices and
curves outside one common plane are not filleted (a line leaving a planar arc's
plane: :mod:`cnc_contour_control.motion.blend_ramp`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.geometry import LineSegment, Segment
from cnc_contour_control.motion.points import POSITION_TOLERANCE_M, FloatArray

_AXIS_EPS = 1.0e-12
_GRID = 33
#: Grid of the fillet angle of the fast measurement (the crossing is then refined by brentq).
_FAST_GRID = 17
_ITERATIONS = 12
#: A fillet is accepted once its deviation reaches this share of the tolerance (or the trims bind).
_CLOSE_ENOUGH = 0.98
#: Secant steps aim this far below the tolerance.
_AIM = 0.999
#: Largest fillet radius per metre of the longer trim allowed (a fillet turning by under 1 mrad is not worth
#: an ArcSegment whose point is computed from a centre far away).
_MAX_RADIUS_PER_TRIM = 1.0e3
#: Largest growth of the radius per secant step.
_MAX_STEP = 4.0
#: Arc left between two fillets on one arc, m: an ArcSegment whose ends are within 1 µm is a full circle.
_ARC_REMAINDER_M = 8.0 * POSITION_TOLERANCE_M


@dataclass(frozen=True)
class Curve:
    """A segment's carrier in its plane's 2-D coordinates (m): a line or a circle.

    ``point`` is a point of the line (the corner) or the circle's centre,
    ``direction`` the line's unit direction, ``radius`` the circle's radius
    (0 for a line) and ``turn`` +1 for counter-clockwise travel, -1 clockwise.
    """

    point: FloatArray
    direction: FloatArray
    radius: float
    turn: float

    @property
    def is_line(self) -> bool:
        """True for a line."""
        return self.radius == 0.0


@dataclass(frozen=True)
class Fillet:
    """A fillet in 2-D plane coordinates (m): centre, radius, tangent points, trims along each neighbour."""

    center: FloatArray
    radius_m: float
    start: FloatArray
    end: FloatArray
    trim_before_m: float
    trim_after_m: float


def common_plane(before: Segment, after: Segment) -> tuple[int, int] | None:
    """The plane of a line-arc or arc-arc corner, or None if a helix or an out-of-plane line takes part."""
    arcs = [s for s in (before, after) if isinstance(s, ArcSegment)]
    if not arcs or any(not arc.is_planar for arc in arcs) or len({arc.plane for arc in arcs}) > 1:
        return None
    plane = arcs[0].plane
    others = [j for j in range(before.n_axes) if j not in plane]
    for line in (s for s in (before, after) if isinstance(s, LineSegment)):
        if np.any(np.abs(line.unit_vector[others]) > _AXIS_EPS):
            return None
    return plane


def carrier(segment: Segment, plane: tuple[int, int], corner: FloatArray) -> Curve:
    """The line or circle carrying ``segment`` in ``plane`` (2-D, m); a line through ``corner``."""
    if isinstance(segment, LineSegment):
        u = segment.unit_vector[list(plane)]
        return Curve(corner, u / float(np.hypot(u[0], u[1])), 0.0, 0.0)
    return Curve(segment.center_m[list(plane)], np.zeros(2), segment.radius_m, segment.direction)


def _left(u: FloatArray) -> FloatArray:
    return np.array([-u[1], u[0]])


def _line_circle(point: FloatArray, u: FloatArray, center: FloatArray, radius: float) -> list[FloatArray]:
    """Intersections of the line ``point + t u`` with the circle (2-D)."""
    offset = point - center
    half_b = float(u @ offset)
    disc = half_b * half_b - (float(offset @ offset) - radius * radius)
    if disc < 0.0:
        return []
    root = math.sqrt(disc)
    return [point + (-half_b - root) * u, point + (-half_b + root) * u]


def _circle_circle(c1: FloatArray, r1: float, c2: FloatArray, r2: float) -> list[FloatArray]:
    """Intersections of two circles (2-D)."""
    delta = c2 - c1
    distance = float(np.hypot(delta[0], delta[1]))
    if distance == 0.0 or distance > r1 + r2 or distance < abs(r1 - r2):
        return []
    along = (r1 * r1 - r2 * r2 + distance * distance) / (2.0 * distance)
    across = math.sqrt(max(r1 * r1 - along * along, 0.0))
    base, normal = c1 + along * delta / distance, _left(delta / distance)
    return [base + across * normal, base - across * normal]


def _offset_centers(first: Curve, second: Curve, signed_m: float) -> list[FloatArray]:
    """Points at left distance ``signed_m`` from both curves (candidate fillet centres)."""
    offsets = []
    for curve in (first, second):
        if curve.is_line:
            offsets.append((curve.point + signed_m * _left(curve.direction), curve.direction, 0.0))
        else:
            radius = curve.radius - curve.turn * signed_m
            if radius <= 0.0:
                return []
            offsets.append((curve.point, curve.direction, radius))
    (p1, u1, r1), (p2, u2, r2) = offsets
    if r1 == 0.0:
        return _line_circle(p1, u1, p2, r2)
    if r2 == 0.0:
        return _line_circle(p2, u2, p1, r1)
    return _circle_circle(p1, r1, p2, r2)


def _foot(curve: Curve, q: FloatArray) -> FloatArray:
    """Nearest point of the (whole) curve to ``q``."""
    if curve.is_line:
        return curve.point + float((q - curve.point) @ curve.direction) * curve.direction
    radial = q - curve.point
    return curve.point + curve.radius * radial / float(np.hypot(radial[0], radial[1]))


def _travel_m(curve: Curve, start: FloatArray, end: FloatArray) -> float:
    """Signed length travelled along the curve from ``start`` to ``end`` (m; arcs: in [-π R, π R))."""
    if curve.is_line:
        return float((end - start) @ curve.direction)
    a0 = math.atan2(start[1] - curve.point[1], start[0] - curve.point[0])
    a1 = math.atan2(end[1] - curve.point[1], end[0] - curve.point[0])
    angle = (curve.turn * (a1 - a0) + math.pi) % (2.0 * math.pi) - math.pi
    return curve.radius * angle


def _tangent(curve: Curve, q: FloatArray) -> FloatArray:
    """Unit direction of travel of the curve at its point ``q``."""
    if curve.is_line:
        return curve.direction
    return curve.turn * _left(q - curve.point) / curve.radius


def _follows(curve: Curve, q: FloatArray, center: FloatArray, side: float) -> bool:
    """True if the fillet (centre ``center``, turning ``side``) runs along the curve's travel at ``q``."""
    along = side * _left(q - center)
    return float(along @ _tangent(curve, q)) > 0.0


def fillet(first: Curve, second: Curve, corner: FloatArray, side: float, radius_m: float) -> Fillet | None:
    """The fillet of radius ``radius_m`` with the shortest trims, or None if the offsets do not meet ahead.

    A candidate counts only if it follows both curves' direction of travel at its tangent points.
    """
    best: Fillet | None = None
    for center in _offset_centers(first, second, side * radius_m):
        start, end = _foot(first, center), _foot(second, center)
        before, after = _travel_m(first, start, corner), _travel_m(second, corner, end)
        if before <= 0.0 or after <= 0.0 or not (_follows(first, start, center, side)
                                                 and _follows(second, end, center, side)):
            continue
        if best is None or before + after < best.trim_before_m + best.trim_after_m:
            best = Fillet(center, radius_m, start, end, before, after)
    return best


def max_trim_m(segment: Segment) -> float:
    """Largest length a fillet may take from ``segment`` (half of it; an arc keeps a few µm between two)."""
    if isinstance(segment, ArcSegment):
        return max(0.5 * (segment.length_m - _ARC_REMAINDER_M), 0.0)
    return 0.5 * segment.length_m


def lift(point_2d: FloatArray, plane: tuple[int, int], corner: FloatArray) -> FloatArray:
    """The n-axis point with ``point_2d`` in ``plane`` and the corner's other coordinates."""
    out = np.array(corner, dtype=float)
    out[list(plane)] = point_2d
    return out


def deviation_m(before: Segment, after: Segment, shape: Fillet, plane: tuple[int, int], corner: FloatArray,
                side: float) -> float:
    """Largest exact distance (m) of the fillet from the two segments (the smaller of both at each point)."""
    from scipy.optimize import minimize_scalar
    rel0 = shape.start - shape.center
    a0 = math.atan2(rel0[1], rel0[0])
    rel1 = shape.end - shape.center
    sweep = (side * (math.atan2(rel1[1], rel1[0]) - a0)) % (2.0 * math.pi)

    def distance(t: FloatArray) -> FloatArray:
        angle = a0 + side * np.atleast_1d(t)
        flat = shape.center + shape.radius_m * np.c_[np.cos(angle), np.sin(angle)]
        points = np.repeat(np.asarray(corner, dtype=float)[None, :], len(angle), axis=0)
        points[:, list(plane)] = flat
        return np.minimum(before.nearest(points)[0], after.nearest(points)[0])

    grid = np.linspace(0.0, sweep, _GRID)
    values = distance(grid)
    i = int(np.argmax(values))
    low, high = grid[max(i - 1, 0)], grid[min(i + 1, _GRID - 1)]
    found = minimize_scalar(lambda t: -float(distance(t)[0]), bounds=(low, high), method="bounded",
                            options={"xatol": 1e-12 * max(sweep, 1e-12)})
    return max(float(values[i]), -float(found.fun))


@dataclass(frozen=True)
class Piece:
    """A segment in its plane's 2-D coordinates (m), for exact distances of points of that plane.

    A line (``radius_m`` 0) from ``start`` along the unit ``direction`` for
    ``length_m``; an arc about ``center`` of ``radius_m`` from
    ``start_angle_rad`` through ``sweep_rad`` turning ``turn`` (+1
    counter-clockwise), from ``start`` to ``end``. Planar segments only (the
    corners :func:`common_plane` accepts), so the in-plane distance is the
    exact one.
    """

    start: tuple[float, float]
    end: tuple[float, float]
    direction: tuple[float, float]
    length_m: float
    center: tuple[float, float]
    radius_m: float
    start_angle_rad: float
    sweep_rad: float
    turn: float

    @classmethod
    def of(cls, segment: Segment, plane: tuple[int, int]) -> Piece:
        """The piece of a line, or of a planar arc, in ``plane``."""
        a, b = plane
        start = (float(segment.start_m[a]), float(segment.start_m[b]))
        end = (float(segment.end_m[a]), float(segment.end_m[b]))
        if isinstance(segment, ArcSegment):
            center = (float(segment.center_m[a]), float(segment.center_m[b]))
            return cls(start, end, (0.0, 0.0), segment.length_m, center, segment.radius_m,
                       segment.start_angle_rad, segment.sweep_rad, segment.direction)
        length = math.hypot(end[0] - start[0], end[1] - start[1])
        direction = ((end[0] - start[0]) / length, (end[1] - start[1]) / length)
        return cls(start, end, direction, length, start, 0.0, 0.0, 0.0, 0.0)

    def distance_m(self, x: float, y: float) -> float:
        """Exact distance (m) from the point ``(x, y)`` of the plane to the segment (as ``Segment.nearest``)."""
        sx, sy = self.start
        if self.radius_m == 0.0:
            ux, uy = self.direction
            along = min(max((x - sx) * ux + (y - sy) * uy, 0.0), self.length_m)
            return math.hypot(x - sx - along * ux, y - sy - along * uy)
        cx, cy = self.center
        angle = (self.turn * (math.atan2(y - cy, x - cx) - self.start_angle_rad)) % (2.0 * math.pi)
        if angle <= self.sweep_rad:
            return abs(math.hypot(x - cx, y - cy) - self.radius_m)
        return min(math.hypot(x - sx, y - sy), math.hypot(x - self.end[0], y - self.end[1]))


def _fillet_angles(shape: Fillet, side: float) -> tuple[float, float]:
    """Angle of the fillet's start about its centre and its sweep (rad, in [0, 2π))."""
    a0 = math.atan2(float(shape.start[1] - shape.center[1]), float(shape.start[0] - shape.center[0]))
    a1 = math.atan2(float(shape.end[1] - shape.center[1]), float(shape.end[0] - shape.center[0]))
    return a0, (side * (a1 - a0)) % (2.0 * math.pi)


def _difference(pair: tuple[float, float]) -> float:
    return pair[0] - pair[1]


def measured_deviation_m(first: Piece, second: Piece, shape: Fillet, side: float) -> float:
    """Largest exact distance (m) of the fillet from the two pieces: :func:`deviation_m`, ~30× faster.

    The smaller of both distances on a grid of the fillet angle; where the
    distance to ``first`` overtakes the one to ``second`` (the crossing, where
    the largest is when each is monotonic) refined by :func:`scipy.optimize.brentq`;
    a grid maximum away from the crossing refined by
    :func:`scipy.optimize.minimize_scalar`, as :func:`deviation_m` does.
    """
    from scipy.optimize import brentq, minimize_scalar
    a0, sweep = _fillet_angles(shape, side)
    cx, cy, r = float(shape.center[0]), float(shape.center[1]), shape.radius_m

    def both(t: float) -> tuple[float, float]:
        x, y = cx + r * math.cos(a0 + side * t), cy + r * math.sin(a0 + side * t)
        return first.distance_m(x, y), second.distance_m(x, y)

    grid = [sweep * i / (_FAST_GRID - 1) for i in range(_FAST_GRID)]
    pairs = [both(t) for t in grid]
    values = [min(pair) for pair in pairs]
    best = max(values)
    i = values.index(best)
    cross = next((j for j, (d1, d2) in enumerate(pairs) if d1 >= d2), None)
    if cross is not None and cross > 0:
        found = brentq(lambda t: _difference(both(t)), grid[cross - 1], grid[cross], xtol=1e-12 * max(sweep, 1e-12))
        best = max(best, min(both(found)))
    if cross is None or i not in (cross - 1, cross):
        low, high = grid[max(i - 1, 0)], grid[min(i + 1, _FAST_GRID - 1)]
        peak = minimize_scalar(lambda t: -min(both(t)), bounds=(low, high), method="bounded",
                               options={"xatol": 1e-12 * max(sweep, 1e-12)})
        best = max(best, -float(peak.fun))
    return best


@dataclass(frozen=True)
class CornerFillet:
    """A planned fillet: its shape (2-D), plane, turn side (+1 left) and measured deviation (m)."""

    shape: Fillet
    plane: tuple[int, int]
    side: float
    deviation_m: float


def _shrunk(shape: Fillet | None, limits: tuple[float, float]) -> float | None:
    """The factor that brings an over-long trim within ``limits`` (None if the trims fit)."""
    if shape is None:
        return 0.5
    ratio = max(shape.trim_before_m / limits[0] if limits[0] > 0 else math.inf,
                shape.trim_after_m / limits[1] if limits[1] > 0 else math.inf)
    return None if ratio <= 1.0 else 0.999 / ratio


def plan_fillet(before: Segment, after: Segment, tolerance_m: float, turn_rad: float) -> CornerFillet | None:
    """The largest fillet of the corner between ``before`` and ``after`` within ``tolerance_m`` (m), or None.

    ``turn_rad`` is the angle between the tangents at the corner, in (0, π).
    None when the corner is not in one plane (helix, out-of-plane line) or no
    fillet fits within the neighbours' shares (:func:`max_trim_m`).
    """
    plane = common_plane(before, after)
    if plane is None:
        return None
    corner = after.start_m
    t1, t2 = before.tangent(before.length_m)[list(plane)], after.tangent(0.0)[list(plane)]
    side = 1.0 if t1[0] * t2[1] - t1[1] * t2[0] > 0.0 else -1.0
    first, second = carrier(before, plane, corner[list(plane)]), carrier(after, plane, corner[list(plane)])
    limits = (max_trim_m(before), max_trim_m(after))
    if min(limits) <= 0.0:
        return None
    high = _MAX_RADIUS_PER_TRIM * max(limits)
    radius, low = min(tolerance_m / (1.0 / math.cos(0.5 * turn_rad) - 1.0), 0.5 * high), 0.0
    pieces = (Piece.of(before, plane), Piece.of(after, plane))
    best: CornerFillet | None = None
    for _ in range(_ITERATIONS):
        shape = fillet(first, second, corner[list(plane)], side, radius)
        factor = _shrunk(shape, limits)
        if factor is not None:
            high, radius = radius, max(radius * factor, 0.5 * (low + radius))
            continue
        assert shape is not None
        deviation = measured_deviation_m(*pieces, shape, side)
        if deviation > tolerance_m:
            high, radius = radius, max(radius * _AIM * tolerance_m / deviation, 0.5 * (low + radius))
            continue
        best, low = CornerFillet(shape, plane, side, deviation), radius
        if deviation >= _CLOSE_ENOUGH * tolerance_m or high <= radius * 1.001:
            break
        radius = min(radius * _AIM * tolerance_m / max(deviation, 1e-300), _MAX_STEP * radius, 0.5 * (radius + high))
    return best
