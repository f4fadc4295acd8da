"""Blends of 3-axis line-arc corners: a line leaving a planar arc's plane (a ramp or plunge into a G17 arc).

The arc lies in the plane ``(a, b)`` at the level ``z_P`` of its axis ``z``
off that plane, the one other axis the line moves. The blend is three
:class:`ArcSegment` pieces (so every consumer takes it as is), each tangent to
the next:

1. the *pitch* piece, in the plane ``(h, z)`` (``h`` the arc-plane axis the
   arc starts heading most along, ``g`` the other one moving linearly: a
   helix): in ``(h, z)`` the fillet of radius ``ρ`` between the line's
   projection and the level ``z = z_P``, so it leaves the line tangent to it
   and ends at ``Q`` level, heading ``h1 = (s c, u_g, 0)`` (``c = hypot(u_h,
   u_z)``, ``s`` the sign of the arc's start heading along ``h``): rising along
   ``g`` at the line's rate ``u_g / c`` per length in ``(h, z)``, its tangent is
   the line's at its start and ``h1`` at its end;
2. and 3. an *S* in the arc's plane at ``z_P``: a circle of radius ``ρ``
   tangent to ``h1`` at ``Q`` turning one way, then one of radius ``ρ`` turning
   the other way, tangent to the first and to the programmed arc (centre at
   ``R - turn σ ρ`` from the arc's centre). The arc angle ``θ`` of the joining
   point solves ``|C1 - C2(θ)| = 2 ρ``, bracketed on a geometric and an even grid and found by
   :func:`scipy.optimize.brentq`.

No single circle can do the second step when the line heads along the arc's
start tangent (``Q`` then lies on that tangent beyond the arc, outside its
circle). An arc followed by a line is blended as the reversed pair. The bound
kept is the measured one: the largest exact distance (``Segment.nearest``) of
the pieces from the line and the arc, on a grid of each piece refined by
:func:`scipy.optimize.minimize_scalar`, at most the tolerance; ``ρ`` shrinks
geometrically from the pitch fillet's own largest within the tolerance
(``P / (1 / cos(γ/2) - 1)``) and the first within it is kept (as one circle
when one joins the arc, else as the S). Helices, lines moving two axes off the arc's plane and plunges without
a move in the plane are not blended.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.blend_fillet import max_trim_m
from cnc_contour_control.motion.geometry import LineSegment, Segment
from cnc_contour_control.motion.points import POSITION_TOLERANCE_M, FloatArray

_AXIS_EPS = 1.0e-12
#: Shrink of the radius per step from the pitch fillet's own largest within the tolerance, and the steps.
_GROWTH = 1.4
_STEPS = 30
_GRID = 33
#: Points of the geometric grid (from ρ/1000 to the arc's share), and of the even one, of where the S joins
#: the arc, on which its tangency is bracketed.
_ANGLE_GRID = 64
_MIN_CHORD_M = 2.0 * POSITION_TOLERANCE_M


@dataclass(frozen=True)
class RampBlend:
    """A blend of pieces from ``pieces[0].start_m`` to ``pieces[-1].end_m``; trims (m) along the segment it
    leaves and the one it joins; ``radius_m`` the pieces' in-plane radius; ``deviation_m`` measured (m)."""

    pieces: tuple[ArcSegment, ...]
    trim_before_m: float
    trim_after_m: float
    radius_m: float
    deviation_m: float


def _reversed_arc(arc: ArcSegment) -> ArcSegment:
    return ArcSegment(arc.end_m, arc.start_m, arc.center_m, not arc.clockwise, arc.plane, arc.feed_m_s)


def _ramp_axis(line: LineSegment, arc: ArcSegment) -> int | None:
    """The one axis off the arc's plane the line moves, or None."""
    if not arc.is_planar or math.hypot(*line.unit_vector[list(arc.plane)]) <= _AXIS_EPS:
        return None
    moving = [j for j in range(line.n_axes) if j not in arc.plane and abs(line.unit_vector[j]) > _AXIS_EPS]
    return moving[0] if len(moving) == 1 else None


def _measure_m(pieces: tuple[ArcSegment, ...], line: Segment, arc: Segment, bound_m: float = math.inf) -> float:
    """Largest exact distance (m) of the pieces from the nearer of ``line`` and ``arc`` (or, where it is over
    ``bound_m`` on the grid already, that grid's largest)."""
    from scipy.optimize import minimize_scalar

    def distance(piece: ArcSegment, s: FloatArray) -> FloatArray:
        points = piece.point(np.atleast_1d(s))
        return np.minimum(line.nearest(points)[0], arc.nearest(points)[0])

    grids = [np.linspace(0.0, piece.length_m, _GRID) for piece in pieces]
    sampled = [distance(piece, grid) for piece, grid in zip(pieces, grids)]
    worst = max(float(values.max()) for values in sampled)
    if worst > bound_m:  # the grid's largest is reached: no refinement can bring it under the bound
        return worst
    for piece, grid, values in zip(pieces, grids, sampled):
        i = int(np.argmax(values))
        low, high = grid[max(i - 1, 0)], grid[min(i + 1, _GRID - 1)]
        found = minimize_scalar(lambda s, p=piece: -float(distance(p, s)[0]), bounds=(low, high), method="bounded",
                                options={"xatol": 1e-12 * max(piece.length_m, 1e-12)})
        worst = max(worst, float(values[i]), -float(found.fun))
    return worst


def _pitch(line: LineSegment, arc: ArcSegment, z: int, rho: float) -> tuple[ArcSegment, FloatArray, float] | None:
    """The pitch piece of radius ``rho``, its end heading and the line's trim (m), or None if it does not fit."""
    a, b = arc.plane
    t = arc.tangent(0.0)
    h, g = (a, b) if abs(t[a]) >= abs(t[b]) else (b, a)
    u, corner = line.unit_vector, arc.start_m
    c, sign = math.hypot(u[h], u[z]), math.copysign(1.0, t[h])
    e_in, e_out = np.array([u[h], u[z]]) / c, np.array([sign, 0.0])
    gamma = math.acos(min(max(float(e_in @ e_out), -1.0), 1.0))
    if not 1e-9 < gamma < math.pi - 1e-6:
        return None
    trim = rho * math.tan(0.5 * gamma)
    if trim / c > max_trim_m(line):
        return None
    toward = e_out - float(e_out @ e_in) * e_in
    start = corner - (trim / c) * u
    center, end = start.copy(), corner.copy()
    center[[h, z]] = start[[h, z]] + rho * toward / math.hypot(*toward)
    end[h], end[g] = corner[h] + sign * trim, start[g] + u[g] / c * rho * gamma
    if math.dist(start, end) <= _MIN_CHORD_M:
        return None
    heading = np.zeros(line.n_axes)
    heading[h], heading[g] = sign * c, u[g]
    clockwise = bool(e_in[0] * e_out[1] - e_in[1] * e_out[0] < 0.0)
    return (ArcSegment(start, end, center, clockwise, (h, z), min(line.feed_m_s, arc.feed_m_s)), heading,
            trim / c)


def _left(v: FloatArray) -> FloatArray:
    return np.array([-v[1], v[0]])


def _ess(q: FloatArray, heading: FloatArray, arc: ArcSegment, rho: float, first_side: float
         ) -> tuple[ArcSegment, ArcSegment, float] | None:
    """The S from ``q`` along ``heading`` onto ``arc``: both circles of radius ``rho``, first turning
    ``first_side`` (+1 left); and the arc length (m) from the arc's start to where it joins, or None."""
    from scipy.optimize import brentq
    a, b = arc.plane
    o, radius, turn = arc.center_m[[a, b]], arc.radius_m, arc.direction
    h = heading[[a, b]] / math.hypot(heading[a], heading[b])
    c1 = q[[a, b]] + first_side * rho * _left(h)
    second = -first_side
    offset = radius - turn * second * rho
    if offset <= 0.0:
        return None
    a0 = arc.start_angle_rad

    def gap(s_m: float) -> float:
        angle = a0 + turn * s_m / radius
        c2 = o + offset * np.array([math.cos(angle), math.sin(angle)])
        return math.dist(c1, c2) - 2.0 * rho

    limit = max_trim_m(arc)
    grid = np.union1d(np.geomspace(min(1e-3 * rho, 0.5 * limit), limit, _ANGLE_GRID),
                      np.linspace(0.0, limit, _ANGLE_GRID + 1)[1:])
    values = [gap(float(s)) for s in grid]
    for i in range(1, len(grid)):
        if values[i - 1] * values[i] > 0.0:
            continue
        travel = float(brentq(gap, float(grid[i - 1]), float(grid[i]), xtol=1e-15))
        angle = a0 + turn * travel / radius
        c2 = o + offset * np.array([math.cos(angle), math.sin(angle)])
        mid2, end2 = 0.5 * (c1 + c2), o + radius * np.array([math.cos(angle), math.sin(angle)])
        # each circle must run the way its neighbours do: the first along ``h`` at ``q``, the second along the arc
        if float(first_side * _left(q[[a, b]] - c1) @ h) <= 0.0 or \
                float(second * _left(end2 - c2) @ (turn * _left(end2 - o))) <= 0.0:
            continue
        mid, end, center1, center2 = (q.copy() for _ in range(4))
        mid[[a, b]], end[[a, b]], center1[[a, b]], center2[[a, b]] = mid2, end2, c1, c2
        if min(math.dist(q, mid), math.dist(mid, end)) <= _MIN_CHORD_M:
            continue
        first = ArcSegment(q, mid, center1, first_side < 0.0, (a, b), arc.feed_m_s)
        last = ArcSegment(mid, end, center2, second < 0.0, (a, b), arc.feed_m_s)
        if max(first.sweep_rad, last.sweep_rad) < math.pi:
            return first, last, travel
    return None


def _circle(q: FloatArray, heading: FloatArray, arc: ArcSegment) -> tuple[ArcSegment, float, float] | None:
    """The one circle tangent to ``heading`` at ``q`` and to ``arc`` (its radius ``r`` solves
    ``|q + σ r n - O| = R - turn σ r``), its radius (m) and where it joins the arc (m along it), or None."""
    a, b = arc.plane
    o, radius, turn = arc.center_m[[a, b]], arc.radius_m, arc.direction
    h = heading[[a, b]] / math.hypot(heading[a], heading[b])
    n, w = _left(h), q[[a, b]] - o
    best = None
    for side in (1.0, -1.0):
        denominator = 2.0 * side * (float(w @ n) + turn * radius)
        r = (radius * radius - float(w @ w)) / denominator if denominator != 0.0 else -1.0
        if not r > 0.0 or radius - turn * side * r <= 0.0:
            continue
        center = q[[a, b]] + side * r * n
        radial = center - o
        end = o + radius * radial / math.hypot(radial[0], radial[1])
        angle = (turn * (math.atan2(radial[1], radial[0]) - arc.start_angle_rad)) % (2.0 * math.pi)
        travel = radius * angle
        if not 0.0 < travel <= max_trim_m(arc) or float(side * _left(end - center) @ (turn * _left(end - o))) <= 0.0:
            continue
        end_m, center_m = q.copy(), q.copy()
        end_m[[a, b]], center_m[[a, b]] = end, center
        if math.dist(q, end_m) <= _MIN_CHORD_M:
            continue
        piece = ArcSegment(q, end_m, center_m, side < 0.0, (a, b), arc.feed_m_s)
        if piece.sweep_rad < math.pi and (best is None or travel < best[2]):
            best = (piece, r, travel)
    return best


def _line_then_arc(line: LineSegment, arc: ArcSegment, tolerance_m: float) -> RampBlend | None:
    z = _ramp_axis(line, arc)
    if z is None:
        return None
    a, b = arc.plane
    t, u = arc.tangent(0.0), line.unit_vector
    h = a if abs(t[a]) >= abs(t[b]) else b
    gamma = math.acos(min(max(math.copysign(1.0, t[h]) * u[h] / math.hypot(u[h], u[z]), -1.0), 1.0))
    if not 1e-9 < gamma < math.pi - 1e-6:
        return None
    rho = min(tolerance_m / (1.0 / math.cos(0.5 * gamma) - 1.0),
              0.999 * max_trim_m(line) * math.hypot(u[h], u[z]) / math.tan(0.5 * gamma))
    for _ in range(_STEPS):
        pitched = _pitch(line, arc, z, rho)
        if pitched is None:
            return None
        pitch, heading, trim = pitched
        options: list[tuple[tuple[ArcSegment, ...], float, float]] = []
        circle = _circle(pitch.end_m, heading, arc)
        if circle is not None:
            options.append(((pitch, circle[0]), min(rho, circle[1]), circle[2]))
        for side in (-arc.direction, arc.direction):
            ess = _ess(pitch.end_m, heading, arc, rho, side)
            if ess is not None:
                options.append(((pitch, ess[0], ess[1]), rho, ess[2]))
        fits = [RampBlend(pieces, trim, travel, r, deviation) for pieces, r, travel in options
                if (deviation := _measure_m(pieces, line, arc, tolerance_m)) <= tolerance_m]
        if fits:
            return max(fits, key=lambda blend: blend.radius_m)
        rho /= _GROWTH
    return None


def plan_ramp(before: Segment, after: Segment, tolerance_m: float) -> RampBlend | None:
    """The blend of a line meeting a planar arc out of its plane (either order) within ``tolerance_m`` (m), or None.

    None for any other corner (helices, lines moving two axes off the arc's plane or none in it) or where no
    blend fits within the tolerance and the neighbours' shares (:func:`~.blend_fillet.max_trim_m`).
    """
    if isinstance(before, LineSegment) and isinstance(after, ArcSegment):
        return _line_then_arc(before, after, tolerance_m)
    if isinstance(before, ArcSegment) and isinstance(after, LineSegment):
        line = LineSegment(after.end_m, after.start_m, after.feed_m_s)
        found = _line_then_arc(line, _reversed_arc(before), tolerance_m)
        if found is None:
            return None
        pieces = tuple(_reversed_arc(piece) for piece in reversed(found.pieces))
        return RampBlend(pieces, found.trim_after_m, found.trim_before_m, found.radius_m, found.deviation_m)
    return None
