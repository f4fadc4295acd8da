"""Arc segments (circular in a plane, helical with the other axes moving linearly); see
:mod:`cnc_contour_control.motion.geometry`."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.motion.points import (
    GOLDEN,
    MIN_LENGTH_M,
    POSITION_TOLERANCE_M,
    RADIUS_TOLERANCE_M,
    TWO_PI,
    FloatArray,
    as_point,
    as_points,
    max_abs_cos,
    require_feed,
)


@dataclass(frozen=True, eq=False)
class ArcSegment:
    """A circular arc in ``plane``; the other axes move linearly with arc length (helix).

    Parameters
    ----------
    start_m, end_m, center_m : array_like, shape (n_axes,)
        Start, end and centre, m. Only the ``plane`` entries of ``center_m`` are used.
        ``end_m`` must lie on the circle (radius difference <= ``RADIUS_TOLERANCE_M``);
        the arc ends at the circle point at the end's angle. An end equal to the start
        in the plane (within ``POSITION_TOLERANCE_M``) makes a full circle.
    clockwise : bool
        Direction seen from the positive normal of ``plane`` (angle decreasing).
    plane : tuple of int
        The two axis indices spanning the arc plane, ``(0, 1)`` = XY.
    feed_m_s : float
        Programmed feed (path speed), m/s, > 0.
    source_line : int, optional
        Line of the source text (G-code) the arc comes from, for messages.

    Notes
    -----
    With helical motion the curvature vector is the exact helix curvature,
    ``r / (r**2 + h**2)`` with ``h`` the rise per radian, pointing to the axis;
    that is the in-plane curvature ``1/r`` scaled by ``(planar length / length)**2``.
    """

    start_m: FloatArray
    end_m: FloatArray
    center_m: FloatArray
    clockwise: bool
    plane: tuple[int, int] = (0, 1)
    feed_m_s: float = math.nan
    #: Line of the source text (G-code) the arc comes from, 1-based; None if none.
    source_line: int | None = None
    radius_m: float = field(init=False)
    sweep_rad: float = field(init=False)
    start_angle_rad: float = field(init=False)
    length_m: float = field(init=False)
    rise_m: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        start = as_point("start_m", self.start_m)
        n_axes = start.size
        end = as_point("end_m", self.end_m, n_axes)
        center = as_point("center_m", self.center_m, n_axes)
        plane = self._check_plane(n_axes)
        if not isinstance(self.clockwise, (bool, np.bool_)):
            raise ProgramError(f"clockwise must be a bool, got {self.clockwise!r}")
        radius, start_angle, sweep = _arc_angles(start, end, center, plane, bool(self.clockwise))
        rise = end - start
        rise[list(plane)] = 0.0
        rise.setflags(write=False)
        length = math.hypot(radius * sweep, float(np.linalg.norm(rise)))
        values = {"start_m": start, "end_m": end, "center_m": center, "plane": plane,
                  "clockwise": bool(self.clockwise), "radius_m": radius, "sweep_rad": sweep,
                  "start_angle_rad": start_angle, "length_m": length, "rise_m": rise,
                  "feed_m_s": require_feed(self.feed_m_s)}
        for name, value in values.items():
            object.__setattr__(self, name, value)

    @classmethod
    def from_validated(cls, values: dict[str, object]) -> ArcSegment:
        """An arc from every field (init and derived, as ``__post_init__`` sets them), without re-checking.

        :func:`cnc_contour_control.motion.segment_batch.arc_segments` is the one caller; it checks and derives
        what ``__post_init__`` does, for many arcs at once.
        """
        arc = object.__new__(cls)
        arc.__dict__.update(values)  # what object.__setattr__ does per field, in one call
        return arc

    def _check_plane(self, n_axes: int) -> tuple[int, int]:
        try:
            a, b = (int(i) for i in self.plane)
        except (TypeError, ValueError) as err:
            raise ProgramError(f"plane must be two axis indices, got {self.plane!r}") from err
        if a == b or not (0 <= a < n_axes and 0 <= b < n_axes):
            raise ProgramError(f"plane must be two distinct axis indices in [0, {n_axes - 1}], got {self.plane!r}")
        return a, b

    @property
    def n_axes(self) -> int:
        """Number of axes."""
        return int(self.start_m.size)

    @property
    def direction(self) -> float:
        """+1 for counter-clockwise, -1 for clockwise."""
        return -1.0 if self.clockwise else 1.0

    @property
    def is_planar(self) -> bool:
        """True when no axis outside the plane moves."""
        return not np.any(self.rise_m)

    def _angle(self, s: FloatArray | float) -> FloatArray | float:
        return self.start_angle_rad + self.direction * self.sweep_rad * s / self.length_m

    def point(self, s_m: ArrayLike) -> FloatArray:
        """Position at arc length ``s_m``, m; shape ``(n_axes,)`` or ``(M, n_axes)``."""
        s = np.clip(np.asarray(s_m, dtype=float), 0.0, self.length_m)
        theta = self._angle(s)
        out = self.start_m + (s / self.length_m)[..., None] * self.rise_m
        a, b = self.plane
        out[..., a] = self.center_m[a] + self.radius_m * np.cos(theta)
        out[..., b] = self.center_m[b] + self.radius_m * np.sin(theta)
        return out

    def tangent(self, s_m: ArrayLike) -> FloatArray:
        """Unit tangent at ``s_m``; shape as :meth:`point`."""
        s = np.clip(np.asarray(s_m, dtype=float), 0.0, self.length_m)
        theta = self._angle(s)
        rate = self.direction * self.radius_m * self.sweep_rad / self.length_m
        out = np.broadcast_to(self.rise_m / self.length_m, s.shape + (self.n_axes,)).copy()
        a, b = self.plane
        out[..., a] = -rate * np.sin(theta)
        out[..., b] = rate * np.cos(theta)
        return out

    def curvature_vector(self, s_m: ArrayLike) -> FloatArray:
        """Curvature vector toward the axis, 1/m; shape as :meth:`point` (see Notes)."""
        s = np.clip(np.asarray(s_m, dtype=float), 0.0, self.length_m)
        theta = self._angle(s)
        kappa = self.radius_m * (self.sweep_rad / self.length_m) ** 2
        out = np.zeros(s.shape + (self.n_axes,))
        a, b = self.plane
        out[..., a] = -kappa * np.cos(theta)
        out[..., b] = -kappa * np.sin(theta)
        return out

    def frame(self, s_m: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Point (m), unit tangent and curvature vector (1/m) at a scalar ``s_m``."""
        s = min(max(s_m, 0.0), self.length_m)
        fraction = s / self.length_m
        theta = self.start_angle_rad + self.direction * self.sweep_rad * fraction
        cos_t, sin_t = math.cos(theta), math.sin(theta)
        omega = self.sweep_rad / self.length_m
        rate, kappa = self.direction * self.radius_m * omega, self.radius_m * omega * omega
        point = self.start_m + fraction * self.rise_m
        tangent = self.rise_m / self.length_m
        curvature = np.zeros(self.n_axes)
        a, b = self.plane
        point[a], point[b] = self.center_m[a] + self.radius_m * cos_t, self.center_m[b] + self.radius_m * sin_t
        tangent[a], tangent[b] = -rate * sin_t, rate * cos_t
        curvature[a], curvature[b] = -kappa * cos_t, -kappa * sin_t
        return point, tangent, curvature

    def _angle_range(self) -> tuple[float, float]:
        end_angle = self.start_angle_rad + self.direction * self.sweep_rad
        return min(self.start_angle_rad, end_angle), max(self.start_angle_rad, end_angle)

    def max_abs_tangent(self) -> FloatArray:
        """Largest ``|tangent_j|`` over the arc per axis, shape ``(n_axes,)`` (exact)."""
        low, high = self._angle_range()
        rate = self.radius_m * self.sweep_rad / self.length_m
        out = np.abs(self.rise_m) / self.length_m
        a, b = self.plane
        out[a] = rate * max_abs_cos(low - math.pi / 2, high - math.pi / 2)
        out[b] = rate * max_abs_cos(low, high)
        return out

    def max_abs_curvature_per_m(self) -> FloatArray:
        """Largest ``|curvature_vector_j|`` over the arc per axis, 1/m, shape ``(n_axes,)``."""
        low, high = self._angle_range()
        kappa = self.radius_m * (self.sweep_rad / self.length_m) ** 2
        out = np.zeros(self.n_axes)
        a, b = self.plane
        out[a] = kappa * max_abs_cos(low, high)
        out[b] = kappa * max_abs_cos(low - math.pi / 2, high - math.pi / 2)
        return out

    def bounding_box_m(self) -> tuple[FloatArray, FloatArray]:
        """Lower and upper corners of a box containing the arc (whole circle in-plane), m."""
        low = np.minimum(self.start_m, self.end_m)
        high = np.maximum(self.start_m, self.end_m)
        for axis in self.plane:
            low[axis] = self.center_m[axis] - self.radius_m
            high[axis] = self.center_m[axis] + self.radius_m
        return low, high

    def nearest(self, points: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Distance from each point to the arc and where it is reached.

        Exact for a planar arc (in any number of axes). For a helix: a grid
        search refined by Newton steps (golden sections where Newton is not
        conclusive); the error is far below 1 nm for machine-sized arcs.
        Arguments and results as :meth:`~cnc_contour_control.motion.geometry.LineSegment.nearest`.
        """
        p = as_points(points, self.n_axes)
        a, b = self.plane
        qa, qb = p[:, a] - self.center_m[a], p[:, b] - self.center_m[b]
        rho = np.hypot(qa, qb)
        phi = np.mod(self.direction * (np.arctan2(qb, qa) - self.start_angle_rad), TWO_PI)
        off = p - self.start_m
        off[:, [a, b]] = 0.0
        if self.is_planar:
            return self._nearest_planar(rho, phi, np.einsum("ij,ij->i", off, off))
        return self._nearest_helix(rho, phi, off)

    def _planar_squared(self, rho: FloatArray, phi: FloatArray, t: FloatArray) -> FloatArray:
        """Squared in-plane distance to the circle point at sweep angle ``t``."""
        return rho * rho + self.radius_m ** 2 - 2.0 * rho * self.radius_m * np.cos(phi - t)

    def _nearest_planar(self, rho: FloatArray, phi: FloatArray, off2: FloatArray) -> tuple[FloatArray, FloatArray]:
        inside = phi <= self.sweep_rad
        to_start = self._planar_squared(rho, phi, np.zeros_like(phi))
        to_end = self._planar_squared(rho, phi, np.full_like(phi, self.sweep_rad))
        at_end = to_end < to_start
        squared = np.where(inside, (rho - self.radius_m) ** 2, np.where(at_end, to_end, to_start))
        t = np.where(inside, phi, np.where(at_end, self.sweep_rad, 0.0))
        distance = np.sqrt(np.maximum(squared + off2, 0.0))
        return distance, t / self.sweep_rad * self.length_m

    def _helix_terms(self, rho: FloatArray, off: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, float]:
        """Coefficients of the squared distance to the helix point at sweep angle ``t``.

        ``d2(t) = c0 - c1 cos(phi - t) - 2 c2 t + c3 t**2`` with per-point
        ``c0 = rho**2 + r**2 + |off|**2``, ``c1 = 2 rho r``, ``c2 = off . rise / sweep``
        and ``c3 = |rise / sweep|**2``.
        """
        c0 = rho * rho + self.radius_m ** 2 + np.einsum("ij,ij->i", off, off)
        c3 = float(self.rise_m @ self.rise_m) / self.sweep_rad ** 2
        return c0, 2.0 * rho * self.radius_m, off @ self.rise_m / self.sweep_rad, c3

    @staticmethod
    def _helix_squared(phi: FloatArray, terms: tuple[FloatArray, ...], t: FloatArray) -> FloatArray:
        c0, c1, c2, c3 = terms
        return c0 - c1 * np.cos(phi - t) - 2.0 * c2 * t + c3 * t * t

    def _nearest_helix(self, rho: FloatArray, phi: FloatArray, off: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Grid search, then safeguarded Newton steps; golden sections where Newton is not conclusive."""
        # c3 is a float: NumPy broadcasts it where the helpers take an array
        terms: tuple[FloatArray, ...] = self._helix_terms(rho, off)  # type: ignore[assignment]  # see above
        grid = np.linspace(0.0, self.sweep_rad, max(17, int(math.ceil(self.sweep_rad / (math.pi / 16.0))) + 1))
        values = self._helix_squared(phi[:, None], tuple(c[:, None] if np.ndim(c) else c for c in terms), grid)
        best = np.argmin(values, axis=1)
        best_value = values[np.arange(rho.size), best]
        step = grid[1] - grid[0]
        low, high = np.maximum(grid[best] - step, 0.0), np.minimum(grid[best] + step, self.sweep_rad)
        t, converged = self._newton(phi, terms, grid[best], low, high)
        refined = self._helix_squared(phi, terms, t)
        retry = np.flatnonzero(~converged | (refined > best_value))
        if retry.size:
            sub = tuple(c[retry] if np.ndim(c) else c for c in terms)
            t[retry], refined[retry] = self._golden(phi[retry], sub, low[retry], high[retry])
        keep_grid = best_value < refined
        t = np.where(keep_grid, grid[best], t)
        squared = np.where(keep_grid, best_value, refined)
        return np.sqrt(np.maximum(squared, 0.0)), t / self.sweep_rad * self.length_m

    def _newton(self, phi: FloatArray, terms: tuple[FloatArray, ...], t: FloatArray, low: FloatArray,
                high: FloatArray, iterations: int = 8) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Newton steps on the squared distance kept inside ``[low, high]``; returns ``t`` and convergence."""
        _, c1, c2, c3 = terms
        step = np.zeros_like(t)
        curvature = np.ones_like(t)
        for _ in range(iterations):
            u = phi - t
            slope = -c1 * np.sin(u) - 2.0 * c2 + 2.0 * c3 * t
            curvature = c1 * np.cos(u) + 2.0 * c3
            step = np.where(curvature > 0.0, -slope / np.where(curvature > 0.0, curvature, 1.0), 0.0)
            moved = np.clip(t + step, low, high)
            step, t = moved - t, moved
        return t, (curvature > 0.0) & (np.abs(step) < 1e-10)

    def _golden(self, phi: FloatArray, terms: tuple[FloatArray, ...], low: FloatArray, high: FloatArray,
                iterations: int = 40) -> tuple[FloatArray, FloatArray]:
        """Vectorised golden-section search of the squared distance on ``[low, high]``.

        Returns the sweep angle found (rad) and the squared distance there (m^2).
        """
        x1, x2 = high - GOLDEN * (high - low), low + GOLDEN * (high - low)
        f1, f2 = self._helix_squared(phi, terms, x1), self._helix_squared(phi, terms, x2)
        for _ in range(iterations):
            left = f1 < f2
            low, high = np.where(left, low, x1), np.where(left, x2, high)
            x_new = np.where(left, high - GOLDEN * (high - low), low + GOLDEN * (high - low))
            f_new = self._helix_squared(phi, terms, x_new)
            x1, x2 = np.where(left, x_new, x2), np.where(left, x1, x_new)
            f1, f2 = np.where(left, f_new, f2), np.where(left, f1, f_new)
        t = 0.5 * (low + high)
        return t, self._helix_squared(phi, terms, t)


def _arc_angles(start: FloatArray, end: FloatArray, center: FloatArray,
                plane: tuple[int, int], clockwise: bool) -> tuple[float, float, float]:
    """Radius (m), start angle (rad) and unsigned sweep (rad, in (0, 2π]) of an arc."""
    a, b = plane
    start_a, start_b = start[a] - center[a], start[b] - center[b]
    end_a, end_b = end[a] - center[a], end[b] - center[b]
    radius, end_radius = math.hypot(start_a, start_b), math.hypot(end_a, end_b)
    if radius < MIN_LENGTH_M:
        raise ProgramError(f"arc radius_m must be > 0, got {radius} (start_m on center_m)")
    if abs(end_radius - radius) > RADIUS_TOLERANCE_M:
        raise ProgramError(
            f"arc end_m is not on the circle: end radius {end_radius:.9g} m, start radius "
            f"{radius:.9g} m, difference {abs(end_radius - radius):.3g} m exceeds tolerance "
            f"{RADIUS_TOLERANCE_M} m")
    start_angle = math.atan2(start_b, start_a)
    if math.hypot(end[a] - start[a], end[b] - start[b]) <= POSITION_TOLERANCE_M:
        return radius, start_angle, TWO_PI
    difference = math.atan2(end_b, end_a) - start_angle
    sweep = (-difference if clockwise else difference) % TWO_PI
    return radius, start_angle, sweep if sweep > 0.0 else TWO_PI
