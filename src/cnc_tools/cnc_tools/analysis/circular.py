"""Circular-test analysis in the manner of ISO 230-4, from recorded positions.

For a program that is one circle (every segment an arc of the same centre,
radius and plane), with ``p`` the measured position in the arc plane, ``c`` the
programmed centre and ``R`` the programmed radius:

- radial deviation ``F = |p - c| - R`` at every sample (nominal centre);
  ``radial_deviation_min_m`` / ``_max_m`` are its extremes, their difference
  ``circular_deviation_nominal_m``;
- circular deviation ``G``: max minus min radius about the least-squares centre
  (ISO 230-4's LSC evaluation), ``circular_deviation_m``;
- mean radius error: ``mean(F)`` (radius lost or gained through servo lag);
- reversal (quadrant) spikes: at every sign change of an axis's velocity (the
  reference's when recorded), the radial deviation farthest from the mean
  radius error within ``window_deg`` of arc around it (the peak), and that peak
  minus the mean radius error (the spike).

Samples are the scored samples given (start and stop transients included).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.core.config import require_range
from cnc_contour_control.motion.geometry import ArcSegment, Program

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Two centres or radii this close are the same circle, m.
SAME_CIRCLE_TOLERANCE_M = 1.0e-9
#: Axis speeds below this fraction of the axis's peak speed carry no sign (rest, not reversal).
REST_FRACTION = 1.0e-3


@dataclass(frozen=True)
class Circle:
    """The programmed circle: ``center_m`` (2,) in the plane's axes, ``radius_m``, axis indices ``plane``."""

    center_m: tuple[float, float]
    radius_m: float
    plane: tuple[int, int]


@dataclass(frozen=True)
class ReversalSpike:
    """Radial deviation peak at one axis velocity reversal (m, degrees, ns)."""

    axis_name: str
    stamp_ns: int
    angle_deg: float
    peak_radial_deviation_m: float
    spike_m: float


@dataclass(frozen=True, eq=False)
class CircularTest:
    """Circular-test quantities of one run (see the module docstring); lengths in m.

    ``angle_rad`` (N,) and ``radial_deviation_m`` (N,) are per sample, about the nominal centre.
    """

    circle: Circle
    axis_names: tuple[str, str]
    n_samples: int
    lsq_center_m: tuple[float, float]
    lsq_radius_m: float
    circular_deviation_m: float
    circular_deviation_nominal_m: float
    radial_deviation_min_m: float
    radial_deviation_max_m: float
    mean_radius_error_m: float
    window_deg: float
    reversals: tuple[ReversalSpike, ...]
    angle_rad: FloatArray
    radial_deviation_m: FloatArray


def circle_of(program: Program) -> Circle | None:
    """The circle that every segment of ``program`` lies on, or ``None`` (lines, several circles)."""
    segments = [s for s in program.segments if isinstance(s, ArcSegment)]
    if len(segments) != len(program.segments):
        return None
    first = segments[0]
    a, b = first.plane
    for seg in segments:
        same_centre = math.hypot(seg.center_m[a] - first.center_m[a], seg.center_m[b] - first.center_m[b])
        if seg.plane != first.plane or same_centre > SAME_CIRCLE_TOLERANCE_M or \
                abs(seg.radius_m - first.radius_m) > SAME_CIRCLE_TOLERANCE_M:
            return None
    return Circle((float(first.center_m[a]), float(first.center_m[b])), float(first.radius_m), (a, b))


def fit_circle(points_m: FloatArray) -> tuple[tuple[float, float], float]:
    """Least-squares circle through planar points (N, 2), m: centre and radius (algebraic fit)."""
    x, y = points_m[:, 0], points_m[:, 1]
    x0, y0 = float(np.mean(x)), float(np.mean(y))
    u, v = x - x0, y - y0
    design = np.column_stack((u, v, np.ones_like(u)))
    solution, *_ = np.linalg.lstsq(design, u * u + v * v, rcond=None)
    cu, cv = 0.5 * solution[0], 0.5 * solution[1]
    radius = math.sqrt(max(solution[2] + cu * cu + cv * cv, 0.0))
    return (x0 + cu, y0 + cv), radius


def reversal_indices(velocity_m_s: FloatArray) -> IntArray:
    """Samples where an axis velocity (N,) changes sign; speeds below ``REST_FRACTION`` of the peak are ignored."""
    v = np.asarray(velocity_m_s, dtype=float)
    finite = np.isfinite(v)
    if not finite.any():
        return np.zeros(0, np.int64)
    threshold = REST_FRACTION * float(np.max(np.abs(v[finite])))
    signs = np.where(finite & (np.abs(v) > threshold), np.sign(v), 0.0)
    moving = np.flatnonzero(signs)
    flips = np.flatnonzero(np.diff(signs[moving]) != 0)
    return moving[flips + 1].astype(np.int64)


def _spike(axis: str, index: int, stamp_ns: IntArray, unwrapped: FloatArray, deviation: FloatArray,
           window_rad: float, mean_m: float) -> ReversalSpike:
    near = np.abs(unwrapped - unwrapped[index]) <= window_rad
    local = deviation[near]
    peak = float(local[np.argmax(np.abs(local - mean_m))])
    angle = math.degrees(unwrapped[index]) % 360.0
    return ReversalSpike(axis, int(stamp_ns[index]), angle, peak, peak - mean_m)


def analyse_circle(circle: Circle, axis_names: tuple[str, ...], stamp_ns: IntArray, position_m: FloatArray,
                   velocity_m_s: FloatArray, *, window_deg: float = 10.0) -> CircularTest:
    """Circular-test quantities from samples on a programmed circle.

    Parameters
    ----------
    circle
        The programmed circle.
    axis_names
        Names of the program's axes (n_axes,).
    stamp_ns
        (N,) sample stamps, ns.
    position_m
        (N, n_axes) measured positions, m.
    velocity_m_s
        (N, n_axes) axis velocities used to find reversals (the reference's, ideally), m/s.
    window_deg
        Half-width of the arc searched around each reversal for its peak, degrees.
    """
    window = require_range("window_deg", window_deg, 0.0, 180.0)
    a, b = circle.plane
    planar = position_m[:, [a, b]] - np.asarray(circle.center_m)
    deviation = np.hypot(planar[:, 0], planar[:, 1]) - circle.radius_m
    angle = np.arctan2(planar[:, 1], planar[:, 0])
    (cx, cy), lsq_radius = fit_circle(position_m[:, [a, b]])
    radii = np.hypot(position_m[:, a] - cx, position_m[:, b] - cy)
    mean_m = float(np.mean(deviation))
    unwrapped = np.unwrap(angle)
    spikes = [(int(stamp_ns[i]), axis_names[axis], int(i)) for axis in (a, b)
              for i in reversal_indices(velocity_m_s[:, axis])]
    reversals = tuple(_spike(name, i, stamp_ns, unwrapped, deviation, math.radians(window), mean_m)
                      for _, name, i in sorted(spikes))
    return CircularTest(
        circle=circle, axis_names=(axis_names[a], axis_names[b]), n_samples=int(deviation.size),
        lsq_center_m=(cx, cy), lsq_radius_m=lsq_radius,
        circular_deviation_m=float(np.ptp(radii)), circular_deviation_nominal_m=float(np.ptp(deviation)),
        radial_deviation_min_m=float(np.min(deviation)), radial_deviation_max_m=float(np.max(deviation)),
        mean_radius_error_m=mean_m, window_deg=window, reversals=reversals,
        angle_rad=angle, radial_deviation_m=deviation)
