"""Contour geometry: line and arc segments and the program they form.

Every array is SI (m) with one entry per machine axis, in the order of the
program's ``axis_names``. Segments are parameterised by their arc length
``s_m`` in ``[0, length_m]``; evaluations outside that range are clamped.
Point-like methods accept a scalar ``s_m`` (result shape ``(n_axes,)``) or
an array of shape ``(M,)`` (result shape ``(M, n_axes)``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnc_contour_control.config import require_positive
from cnc_contour_control.errors import ConfigError, ProgramError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Two points closer than this are the same point (contiguity, full circles), m.
POSITION_TOLERANCE_M = 1.0e-6
#: Largest allowed difference between an arc's end and start radius, m (as LinuxCNC: 0.002 mm).
RADIUS_TOLERANCE_M = 2.0e-6
#: Shortest segment (and smallest radius) accepted, m.
MIN_LENGTH_M = 1.0e-9
_TWO_PI = 2.0 * math.pi
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def as_point(name: str, value: ArrayLike, n_axes: int | None = None) -> FloatArray:
    """Validate one point: a finite, read-only float array of shape ``(n_axes,)``, m."""
    array = np.array(value, dtype=float)
    if array.ndim != 1 or array.size == 0:
        raise ProgramError(f"{name} must be a 1-D array with one entry per axis, got shape {array.shape}")
    if n_axes is not None and array.size != n_axes:
        raise ProgramError(f"{name} must have {n_axes} entries (one per axis), got {array.size}")
    if not np.all(np.isfinite(array)):
        raise ProgramError(f"{name} must be finite, got {array.tolist()}")
    array.setflags(write=False)
    return array


def as_points(points: ArrayLike, n_axes: int) -> FloatArray:
    """Validate a batch of points: float array of shape ``(N, n_axes)``, m."""
    array = np.asarray(points, dtype=float)
    if array.ndim == 1 and array.size == n_axes:
        array = array.reshape(1, n_axes)
    if array.ndim != 2 or array.shape[1] != n_axes:
        raise ProgramError(f"points must have shape (N, {n_axes}), got {array.shape}")
    return array


def _require_feed(feed_m_s: float) -> float:
    try:
        return require_positive("feed_m_s", feed_m_s)
    except ConfigError as err:
        raise ProgramError(str(err)) from err


def _max_abs_cos(low_rad: float, high_rad: float) -> float:
    """Largest ``|cos θ|`` for θ in ``[low_rad, high_rad]``."""
    k = math.ceil(low_rad / math.pi)
    if k * math.pi <= high_rad:
        return 1.0
    return max(abs(math.cos(low_rad)), abs(math.cos(high_rad)))


@dataclass(frozen=True, eq=False)
class LineSegment:
    """A straight segment from ``start_m`` to ``end_m`` at feed ``feed_m_s``.

    Parameters
    ----------
    start_m, end_m : array_like, shape (n_axes,)
        End points, m.
    feed_m_s : float
        Programmed feed (path speed), m/s, > 0.
    """

    start_m: FloatArray
    end_m: FloatArray
    feed_m_s: float
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
        object.__setattr__(self, "feed_m_s", _require_feed(self.feed_m_s))

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

    def signed_error(self, points: ArrayLike, plane: tuple[int, int] = (0, 1)) -> FloatArray:
        """Signed distance (m, shape ``(N,)``) from the infinite line in ``plane``, left of travel > 0."""
        relative = as_points(points, self.n_axes) - self.start_m
        a, b = plane
        direction = self.unit_vector[[a, b]]
        norm = float(np.hypot(direction[0], direction[1]))
        if norm < 1e-12:
            raise ProgramError(f"line does not move in plane {plane}; signed_error is undefined")
        return (direction[0] * relative[:, b] - direction[1] * relative[:, a]) / norm


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
                  "feed_m_s": _require_feed(self.feed_m_s)}
        for name, value in values.items():
            object.__setattr__(self, name, value)

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
        out[a] = rate * _max_abs_cos(low - math.pi / 2, high - math.pi / 2)
        out[b] = rate * _max_abs_cos(low, high)
        return out

    def max_abs_curvature_per_m(self) -> FloatArray:
        """Largest ``|curvature_vector_j|`` over the arc per axis, 1/m, shape ``(n_axes,)``."""
        low, high = self._angle_range()
        kappa = self.radius_m * (self.sweep_rad / self.length_m) ** 2
        out = np.zeros(self.n_axes)
        a, b = self.plane
        out[a] = kappa * _max_abs_cos(low, high)
        out[b] = kappa * _max_abs_cos(low - math.pi / 2, high - math.pi / 2)
        return out

    def bounding_box_m(self) -> tuple[FloatArray, FloatArray]:
        """Lower and upper corners of a box containing the arc (whole circle in-plane), m."""
        low = np.minimum(self.start_m, self.end_m)
        high = np.maximum(self.start_m, self.end_m)
        for axis in self.plane:
            low[axis] = self.center_m[axis] - self.radius_m
            high[axis] = self.center_m[axis] + self.radius_m
        return low, high

    def signed_error(self, points: ArrayLike) -> FloatArray:
        """Radial deviation in the plane, ``|p - c| - r`` (m, shape ``(N,)``), > 0 outside."""
        p = as_points(points, self.n_axes)
        a, b = self.plane
        return np.hypot(p[:, a] - self.center_m[a], p[:, b] - self.center_m[b]) - self.radius_m

    def nearest(self, points: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Distance from each point to the arc and where it is reached.

        Exact for a planar arc (in any number of axes). For a helix: a grid
        search refined by Newton steps (golden sections where Newton is not
        conclusive); the error is far below 1 nm for machine-sized arcs.

        Parameters
        ----------
        points : array_like, shape (N, n_axes)
            Positions, m.

        Returns
        -------
        distance_m, s_m : ndarray, shape (N,)
            Distance to the nearest point of the arc (m) and its arc length (m).
        """
        p = as_points(points, self.n_axes)
        a, b = self.plane
        qa, qb = p[:, a] - self.center_m[a], p[:, b] - self.center_m[b]
        rho = np.hypot(qa, qb)
        phi = np.mod(self.direction * (np.arctan2(qb, qa) - self.start_angle_rad), _TWO_PI)
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
        terms = self._helix_terms(rho, off)
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
        x1, x2 = high - _GOLDEN * (high - low), low + _GOLDEN * (high - low)
        f1, f2 = self._helix_squared(phi, terms, x1), self._helix_squared(phi, terms, x2)
        for _ in range(iterations):
            left = f1 < f2
            low, high = np.where(left, low, x1), np.where(left, x2, high)
            x_new = np.where(left, high - _GOLDEN * (high - low), low + _GOLDEN * (high - low))
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
        return radius, start_angle, _TWO_PI
    difference = math.atan2(end_b, end_a) - start_angle
    sweep = (-difference if clockwise else difference) % _TWO_PI
    return radius, start_angle, sweep if sweep > 0.0 else _TWO_PI


Segment = Union[LineSegment, ArcSegment]


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
    """

    name: str
    axis_names: tuple[str, ...]
    segments: tuple[Segment, ...]
    segment_start_m: FloatArray = field(init=False, repr=False)
    total_length_m: float = field(init=False)

    def __post_init__(self) -> None:
        axes = tuple(self.axis_names)
        if not axes or len(set(axes)) != len(axes) or not all(isinstance(n, str) and n for n in axes):
            raise ProgramError(f"axis_names must be distinct non-empty names, got {list(axes)}")
        segments = tuple(self.segments)
        if not segments:
            raise ProgramError(f"program {self.name!r} has no segments")
        for index, segment in enumerate(segments):
            _check_segment(index, segment, axes, segments[index - 1] if index else None)
        lengths = np.array([segment.length_m for segment in segments])
        starts = np.concatenate(([0.0], np.cumsum(lengths)[:-1]))
        starts.setflags(write=False)
        object.__setattr__(self, "axis_names", axes)
        object.__setattr__(self, "segments", segments)
        object.__setattr__(self, "segment_start_m", starts)
        object.__setattr__(self, "total_length_m", float(np.sum(lengths)))

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

    def contour_distance(self, points: ArrayLike) -> tuple[FloatArray, IntArray]:
        """Exact distance from each point to the whole contour.

        Segments whose bounding box is farther than the best distance found so
        far are skipped for that point.

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
        for i, segment in enumerate(self.segments):
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
