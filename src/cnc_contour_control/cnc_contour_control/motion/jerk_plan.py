"""The jerk-limited planner mode (``AxisLimits.max_jerk_m_s3`` set): an S-curve per segment, rest to rest.

Each segment is run from rest to rest by :class:`~cnc_contour_control.motion.jerk_profile.SCurve` under path
limits ``V``, ``A``, ``J`` chosen so that every axis keeps its velocity, acceleration and jerk limit on every
point of the segment. With ``t_j``, ``k_j`` and ``k'_j`` the largest ``|T_j|``, ``|K_j|`` and ``|dK_j/ds|`` of
the segment (unit tangent ``T``, curvature vector ``K``) the axis values are bounded term by term:

    |v_j| <= v t_j
    |a_j| <= |a_t| t_j + v² k_j
    |j_j| <= |j_t| t_j + 3 v |a_t| k_j + v³ k'_j

A line (``k = k' = 0``) gets ``V = min(feed, vmax_j / t_j)``, ``A = min(amax_j / t_j)``, ``J = min(jmax_j / t_j)``.
An arc (helix: in-plane radius ``r``, angle rate ``ω = sweep / length``, ``κ = r ω²``, ``k' = κ ω`` on its
plane's axes) gives half of each acceleration limit to each term and a third of each jerk limit to each:
``v² k_j <= amax_j / 2``, ``A t_j <= amax_j / 2``, ``v³ k'_j <= jmax_j / 3``, ``3 V A k_j <= jmax_j / 3``,
``J t_j <= jmax_j / 3``. Every junction is an exact stop (speed and acceleration 0), so the acceleration
never steps and the path is the programmed one (deviation 0); a dwell (G4) waits at its junction.
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import Program, Segment
from cnc_contour_control.motion.jerk_profile import SCurve

FloatArray = NDArray[np.float64]
_TINY = 1.0e-300


@dataclass(frozen=True)
class PathLimits:
    """Path speed (m/s), tangential acceleration (m/s²) and tangential jerk (m/s³) of one segment."""

    speed_m_s: float
    accel_m_s2: float
    jerk_m_s3: float


def segment_path_limits(segment: Segment, limits: AxisLimits, clamp_feed: bool = True) -> PathLimits:
    """The path limits under which ``segment`` keeps every axis's limits (module notes)."""
    jerk_limits = limits.max_jerk_m_s3
    if jerk_limits is None:
        raise ConfigError("max_jerk_m_s3 must be set for the jerk-limited planner, got None")
    vmax, amax = np.asarray(limits.max_velocity_m_s), np.asarray(limits.max_acceleration_m_s2)
    jmax = np.asarray(jerk_limits)
    tangent = np.asarray(segment.max_abs_tangent(), dtype=float)
    speed = min(segment.feed_m_s, float(np.min(vmax / np.maximum(tangent, _TINY))))
    if speed < segment.feed_m_s * (1.0 - 1e-12) and not clamp_feed:
        raise ConfigError(f"feed {segment.feed_m_s} m/s exceeds the axis velocity limits (largest {speed} m/s on "
                          "this segment); set clamp_feed to slow it down")
    if not isinstance(segment, ArcSegment):
        return PathLimits(speed, float(np.min(amax / np.maximum(tangent, _TINY))),
                          float(np.min(jmax / np.maximum(tangent, _TINY))))
    curvature = np.asarray(segment.max_abs_curvature_per_m(), dtype=float)
    omega = segment.sweep_rad / segment.length_m
    rate = np.zeros_like(curvature)
    rate[list(segment.plane)] = segment.radius_m * omega ** 3
    speed = min(speed, float(np.min(np.sqrt(0.5 * amax / np.maximum(curvature, _TINY)))),
                float(np.min(np.cbrt(jmax / (3.0 * np.maximum(rate, _TINY))))))
    accel = min(float(np.min(0.5 * amax / np.maximum(tangent, _TINY))),
                float(np.min(jmax / (9.0 * speed * np.maximum(curvature, _TINY)))))
    return PathLimits(speed, accel, float(np.min(jmax / (3.0 * np.maximum(tangent, _TINY)))))


class JerkPlan:
    """The jerk-limited plan of ``program`` under ``limits`` (with ``max_jerk_m_s3``): one S-curve per segment.

    :attr:`start_s` (``(n_segments + 1,)``) is each segment's start time, s, the last entry the plan's end;
    :meth:`path_state` gives segment, local arc length, speed, acceleration and jerk at any times.
    """

    def __init__(self, program: Program, limits: AxisLimits, clamp_feed: bool = True) -> None:
        if limits.max_jerk_m_s3 is None:
            raise ConfigError("max_jerk_m_s3 must be set for the jerk-limited planner, got None")
        self.program = program
        self.path_limits = [segment_path_limits(s, limits, clamp_feed) for s in program.segments]
        self.curves = [SCurve(s.length_m, p.speed_m_s, p.accel_m_s2, p.jerk_m_s3)
                       for s, p in zip(program.segments, self.path_limits)]
        dwell = program.junction_dwell_s
        starts, t = [], 0.0
        for k, curve in enumerate(self.curves):
            t += float(dwell[k])
            starts.append(t)
            t += curve.duration_s
        self.start_s = np.array(starts + [t + float(dwell[-1])])
        self._start_list = starts

    @property
    def duration_s(self) -> float:
        """The plan's duration, s (the last dwell included)."""
        return float(self.start_s[-1])

    @property
    def peak_speed_m_s(self) -> FloatArray:
        """Each segment's peak path speed, m/s, ``(n_segments,)``."""
        return np.array([curve.peak_m_s for curve in self.curves])

    def path_state(self, times_s: ArrayLike) -> tuple[NDArray[np.intp], FloatArray, FloatArray, FloatArray,
                                                     FloatArray]:
        """Segment index, local arc length (m), speed (m/s), acceleration (m/s²), jerk (m/s³) at ``times_s``."""
        t = np.asarray(times_s, dtype=float).reshape(-1)
        index = np.clip(np.searchsorted(self.start_s[:-1], t, side="right") - 1, 0, len(self.curves) - 1)
        out = [np.zeros(t.size) for _ in range(4)]
        for k in np.unique(index).tolist():
            rows = np.flatnonzero(index == k)
            for column, values in zip(out, self.curves[k].evaluate(t[rows] - self.start_s[k])):
                column[rows] = values
        return index.astype(np.intp), out[0], out[1], out[2], out[3]

    def segment_at(self, t_s: float) -> int:
        """The index of the segment running at ``t_s`` (s)."""
        return min(max(bisect.bisect_right(self._start_list, t_s) - 1, 0), len(self.curves) - 1)

    def axis_arrays(self, times_s: ArrayLike) -> tuple[NDArray[np.intp], FloatArray, FloatArray, FloatArray,
                                                      FloatArray, FloatArray]:
        """Segment, local arc length (m), path speed (m/s) and axis position (m), velocity (m/s), acceleration
        (m/s²) ``(M, n_axes)`` at ``times_s``."""
        index, s_local, speed, accel, _ = self.path_state(times_s)
        n = self.program.n_axes
        position, velocity, acceleration = (np.zeros((index.size, n)) for _ in range(3))
        for k in np.unique(index).tolist():
            rows = np.flatnonzero(index == k)
            segment = self.program.segments[k]
            tangent = segment.tangent(s_local[rows])
            position[rows] = segment.point(s_local[rows])
            velocity[rows] = speed[rows, None] * tangent
            acceleration[rows] = (accel[rows, None] * tangent
                                  + (speed[rows] ** 2)[:, None] * segment.curvature_vector(s_local[rows]))
        return index, s_local, speed, position, velocity, acceleration
