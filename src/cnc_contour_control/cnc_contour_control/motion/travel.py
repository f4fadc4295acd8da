"""Soft travel limits: the box the planned path must stay in (ROS-free).

A limited axis ``j`` has a travel ``[min_j, max_j]`` (mm); the others are
unbounded. A program is checked on its PLANNED path (blends included): each
segment's exact axis-aligned extent

    line    the box of its two ends
    arc     its ends, plus in its plane the circle's extreme points
            (angles 0, π/2, π, 3π/2) that lie between its start and end angles;
            the other axes of a helix move linearly (ends suffice)

must lie in the box; the first segment (in program order) that leaves it is
refused naming its G-code line (``source_line``), the axis and by how much,
before any axis moves. A joint trajectory of one axis is checked the same way
on its interpolant: linear between points, or each cubic Hermite piece's
extremes (where its time derivative vanishes).

The reference is a point of the planned path (the feed profile only decides
when), and an acceleration/deceleration filter averages past references with
non-negative weights: both stay in a convex box the path stays in.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cnc_contour_control.core.config import require_names
from cnc_contour_control.core.errors import ConfigError, FaultError, ProgramError
from cnc_contour_control.core.params import param
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.geometry import Program, Segment
from cnc_contour_control.motion.points import FloatArray

#: An excess below this is rounding, not a path leaving the box, m (1 nm).
TRAVEL_TOLERANCE_M = 1.0e-9


@dataclass(frozen=True)
class TravelLimits:
    """Soft travel limits of some axes (the interpolator's parameters; empty: every axis unbounded).

    Parameters
    ----------
    travel_axes : tuple of str
        The limited axes (the interpolator's default: every axis, in order).
    travel_min_mm, travel_max_mm : tuple of float
        Lowest and highest position of each axis of ``travel_axes``, mm, finite, ``min < max``; both empty:
        no limits (``travel_axes`` is then ignored).
    """

    travel_axes: tuple[str, ...] = param((), read_only=True,
                                         description="the axes travel_min_mm and travel_max_mm limit, one value "
                                                     "each (the interpolator's default: every axis)")
    travel_min_mm: tuple[float, ...] = param((), unit="mm", read_only=True,
                                             description="lowest position of each axis of travel_axes")
    travel_max_mm: tuple[float, ...] = param((), unit="mm", read_only=True,
                                             description="highest position of each axis of travel_axes")

    def __post_init__(self) -> None:
        low, high = _floats("travel_min_mm", self.travel_min_mm), _floats("travel_max_mm", self.travel_max_mm)
        axes = require_names("travel_axes", self.travel_axes) if low or high else ()
        if not len(low) == len(high) == len(axes):
            raise ConfigError(f"travel_min_mm and travel_max_mm need one value per travel_axes entry "
                              f"({len(axes)}: {list(axes)}), got {len(low)} and {len(high)}")
        for name, a, b in zip(axes, low, high):
            if not a < b:
                raise ConfigError(f"travel_min_mm must be < travel_max_mm for axis {name}, got {a} and {b}")
        for name, value in (("travel_axes", axes), ("travel_min_mm", low), ("travel_max_mm", high)):
            object.__setattr__(self, name, value)

    @classmethod
    def of(cls, travel_mm: dict[str, Sequence[float]]) -> TravelLimits:
        """From ``{axis: [min_mm, max_mm]}`` (the scenario's ``limits.travel_mm``)."""
        for axis, pair in travel_mm.items():
            if not isinstance(pair, (list, tuple)) or len(pair) != 2:
                raise ConfigError(f"travel_mm.{axis} must be [min_mm, max_mm], got {pair!r}")
        return cls(tuple(travel_mm), tuple(p[0] for p in travel_mm.values()), tuple(p[1] for p in travel_mm.values()))

    @property
    def active(self) -> bool:
        """True when some axis is limited."""
        return bool(self.travel_axes)

    def bounds_m(self, axes: Sequence[str]) -> tuple[FloatArray, FloatArray]:
        """Lowest and highest position per axis of ``axes`` (m, shape ``(n_axes,)``; ±inf where unbounded)."""
        unknown = sorted(set(self.travel_axes) - set(axes))
        if unknown:
            raise ConfigError(f"travel_axes names {unknown[0]!r}, not an axis of the machine {list(axes)}")
        low, high = np.full(len(axes), -math.inf), np.full(len(axes), math.inf)
        for name, a, b in zip(self.travel_axes, self.travel_min_mm, self.travel_max_mm):
            low[list(axes).index(name)], high[list(axes).index(name)] = a * 1e-3, b * 1e-3
        return low, high

    def limit_mm(self, axis: str) -> tuple[float, float]:
        """``(min_mm, max_mm)`` of one axis (±inf if it is not limited)."""
        if axis not in self.travel_axes:
            return -math.inf, math.inf
        i = self.travel_axes.index(axis)
        return self.travel_min_mm[i], self.travel_max_mm[i]

    def check_program(self, program: Program) -> None:
        """Refuse (ProgramError) a planned program leaving the box: see :func:`check_program`."""
        if self.active:
            check_program(program, *self.bounds_m(program.axis_names))


def _floats(name: str, values: Sequence[float]) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in values)
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{name} must be a list of numbers (mm), got {values!r}") from err
    for value in out:
        if not math.isfinite(value):
            raise ConfigError(f"{name} must be finite, got {value!r}")
    return out


def segment_extent_m(segment: Segment) -> tuple[FloatArray, FloatArray]:
    """The exact lowest and highest position per axis a segment reaches, m, each ``(n_axes,)`` (module notes)."""
    low, high = np.minimum(segment.start_m, segment.end_m), np.maximum(segment.start_m, segment.end_m)
    if not isinstance(segment, ArcSegment):
        return low, high
    a, b = segment.plane
    first = segment.start_angle_rad
    last = first + segment.direction * segment.sweep_rad
    lo_rad, hi_rad = min(first, last), max(first, last)
    for quarter in range(4):
        angle = quarter * math.pi / 2
        if math.ceil((lo_rad - angle) / (2 * math.pi)) * 2 * math.pi + angle > hi_rad:
            continue  # no turn of this extreme angle between the start and end angles
        axis = a if quarter in (0, 2) else b  # cos extremes on the first plane axis, sin on the second
        value = segment.center_m[axis] + segment.radius_m * (1.0 if quarter in (0, 1) else -1.0)
        low[axis], high[axis] = min(low[axis], value), max(high[axis], value)
    return low, high


def check_program(program: Program, low_m: FloatArray, high_m: FloatArray) -> None:
    """Refuse (ProgramError) the first segment reaching outside ``[low_m, high_m]`` (m, per axis).

    The message names the G-code line (or the segment), the axis, where the path reaches and by how much, mm.
    Ends as arrays for every segment at once, arcs' extremes one by one (200 000 lines: 0.3 s, 3 s in a loop).
    """
    segments = program.segments
    starts, ends = np.array([s.start_m for s in segments]), np.array([s.end_m for s in segments])
    seg_low, seg_high = np.minimum(starts, ends), np.maximum(starts, ends)
    for index, segment in enumerate(segments):
        if isinstance(segment, ArcSegment):
            seg_low[index], seg_high[index] = segment_extent_m(segment)
    excess_m = np.maximum(low_m - seg_low, seg_high - high_m)
    outside = np.flatnonzero(np.max(excess_m, axis=1) > TRAVEL_TOLERANCE_M)
    if outside.size:
        index = int(outside[0])
        _refuse(program, index, seg_low[index], seg_high[index], low_m, high_m)


def _refuse(program: Program, index: int, seg_low: FloatArray, seg_high: FloatArray, low_m: FloatArray,
            high_m: FloatArray) -> None:
    """The ProgramError of segment ``index``, whose extent ``[seg_low, seg_high]`` leaves the box."""
    below, above = low_m - seg_low, seg_high - high_m
    worst = int(np.argmax(np.maximum(below, above)))
    excess_m = float(max(below[worst], above[worst]))
    side, reach_m, bound_m = ("min", seg_low[worst], low_m[worst]) if below[worst] >= above[worst] else (
        "max", seg_high[worst], high_m[worst])
    line = getattr(program.segments[index], "source_line", None)
    where = f"line {line}" if line else f"segment {index}"
    raise ProgramError(f"travel limit: {where} takes axis {program.axis_names[worst]} to "
                       f"{1e3 * reach_m:.6f} mm, {1e3 * excess_m:.6f} mm beyond its travel_{side}_mm "
                       f"{1e3 * bound_m:.10g}; refused before any axis moves")


def trajectory_extent_m(times_s: Sequence[float], positions_m: Sequence[float],
                        velocities_m_s: Sequence[float] | None, held: bool = False) -> list[tuple[float, str]]:
    """Every extreme of a one-axis trajectory's interpolant: ``(position m, where)`` (module notes).

    The points themselves and, with velocities, each cubic Hermite piece's interior extremes (the roots of
    its derivative in (0, 1)). ``held``: the first point is the reference held when the trajectory is taken
    up, the message's points counted after it.
    """
    def name(i: int) -> str:
        return "the held reference" if held and i == 0 else f"point {i - held}"

    out = [(float(p), name(i)) for i, p in enumerate(positions_m)]
    if velocities_m_s is None:
        return out
    for i in range(len(times_s) - 1):
        h_s = times_s[i + 1] - times_s[i]
        p0, p1, v0, v1 = positions_m[i], positions_m[i + 1], h_s * velocities_m_s[i], h_s * velocities_m_s[i + 1]
        # d/ds of the Hermite cubic (s in [0, 1]): qa s^2 + qb s + qc
        qa, qb, qc = 6 * (p0 - p1) + 3 * v0 + 3 * v1, -6 * (p0 - p1) - 4 * v0 - 2 * v1, v0
        for s in _unit_roots(qa, qb, qc):
            s2, s3 = s * s, s * s * s
            out.append(((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * v0 + (3 * s2 - 2 * s3) * p1
                        + (s3 - s2) * v1, f"between {name(i)} and {name(i + 1)}"))
    return out


def _unit_roots(qa: float, qb: float, qc: float) -> list[float]:
    """Real roots of ``qa s² + qb s + qc`` in (0, 1)."""
    if abs(qa) < 1e-300:
        roots = [] if abs(qb) < 1e-300 else [-qc / qb]
    else:
        disc = qb * qb - 4 * qa * qc
        if disc < 0:
            return []
        root = math.sqrt(disc)
        roots = [(-qb - root) / (2 * qa), (-qb + root) / (2 * qa)]
    return [s for s in roots if 0.0 < s < 1.0]


def check_trajectory(axis: str, travel_mm: tuple[float, float], times_s: Sequence[float],
                     positions_m: Sequence[float], velocities_m_s: Sequence[float] | None,
                     held: bool = False) -> None:
    """Refuse (FaultError) a one-axis trajectory whose interpolant leaves ``travel_mm`` = ``(min, max)``, mm.

    ``held`` as :func:`trajectory_extent_m`.
    """
    low_mm, high_mm = travel_mm
    for position_m, where in trajectory_extent_m(times_s, positions_m, velocities_m_s, held):
        value_mm = 1e3 * position_m
        excess_mm = max(low_mm - value_mm, value_mm - high_mm)
        if excess_mm * 1e-3 <= TRAVEL_TOLERANCE_M:
            continue
        side, bound = ("min", low_mm) if value_mm < low_mm else ("max", high_mm)
        raise FaultError(f"travel limit: joint_trajectory {where} takes axis {axis} "
                         f"to {value_mm:.6f} mm, {excess_mm:.6f} mm beyond its travel_{side}_mm {bound:.10g}")
