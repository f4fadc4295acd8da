"""The jerk-limited planner mode (``AxisLimits.max_jerk_m_s3`` set): S-curves along segments, corners at speed.

Each segment is run by :class:`~cnc_contour_control.motion.jerk_profile.SCurve` between its junctions'
speeds under path limits ``V``, ``A``, ``J`` chosen so that every axis keeps its velocity, acceleration and jerk
limit on every point of the segment. With ``t_j``, ``k_j`` and ``k'_j`` the largest ``|T_j|``, ``|K_j|`` and
``|dK_j/ds|`` of the segment (unit tangent ``T``, curvature vector ``K``) the axis values are bounded term by term:

    |v_j| <= v t_j
    |a_j| <= |a_t| t_j + v² k_j
    |j_j| <= |j_t| t_j + 3 v |a_t| k_j + v³ k'_j

A line (``k = k' = 0``) gets ``V = min(feed, vmax_j / t_j)``, ``A = min(amax_j / t_j)``, ``J = min(jmax_j / t_j)``.
An arc (helix: in-plane radius ``r``, angle rate ``ω = sweep / length``, ``κ = r ω²``, ``k' = κ ω`` on its
plane's axes) gives half of each acceleration limit to each term and a third of each jerk limit to each:
``v² k_j <= amax_j / 2``, ``A t_j <= amax_j / 2``, ``v³ k'_j <= jmax_j / 3``, ``3 V A k_j <= jmax_j / 3``,
``J t_j <= jmax_j / 3``; its junctions are exact stops (speed and acceleration 0). A line-line corner is
passed at speed by a velocity blend (:mod:`~cnc_contour_control.motion.jerk_blend`) within the path tolerance;
the acceleration never steps anywhere. A dwell (G4) waits at its junction, which is a stop.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import Program, Segment
from cnc_contour_control.motion.jerk_blend import Corner, CornerAxes, corner_speed_m_s, corner_time_s
from cnc_contour_control.motion.jerk_profile import SCurve, reachable_m_s

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
    """The jerk-limited plan of ``program`` under ``limits`` (with ``max_jerk_m_s3``) and a path tolerance.

    Line-line corners are passed at speed within ``tolerance_m`` (:mod:`~cnc_contour_control.motion.jerk_blend`);
    every other junction, a dwell's, and every corner at tolerance 0 is an exact stop. Each segment's remaining
    piece is an S-curve between its junctions' speeds; the junction speeds come from a backward and a forward
    pass (each reachable from the next and the previous within the piece between).
    """

    def __init__(self, program: Program, limits: AxisLimits, clamp_feed: bool = True,
                 tolerance_m: float = 0.0) -> None:
        if limits.max_jerk_m_s3 is None:
            raise ConfigError("max_jerk_m_s3 must be set for the jerk-limited planner, got None")
        self.program = program
        self.path_limits = [segment_path_limits(s, limits, clamp_feed) for s in program.segments]
        self._axes = CornerAxes(np.asarray(limits.max_acceleration_m_s2), np.asarray(limits.max_jerk_m_s3))
        self._tangents = tangents = [(s.tangent(0.0), s.tangent(s.length_m)) for s in program.segments]
        self._changes = [np.zeros(program.n_axes)] + [np.abs(tangents[k][0] - tangents[k - 1][1])
                                                      for k in range(1, len(tangents))] + [np.zeros(program.n_axes)]
        self.junction_speeds_m_s = self._junction_speeds(tolerance_m)
        self._corner_times = [self._corner_time(k) for k in range(len(program.segments) + 1)]
        self._trims = [t * 0.5 * float(v) for t, v in zip(self._corner_times, self.junction_speeds_m_s.tolist())]
        self.curves = [SCurve(max(seg.length_m - self._trims[k] - self._trims[k + 1], 0.0), p.speed_m_s,
                              p.accel_m_s2, p.jerk_m_s3, float(self.junction_speeds_m_s[k]),
                              float(self.junction_speeds_m_s[k + 1]))
                       for k, (seg, p) in enumerate(zip(program.segments, self.path_limits))]
        self._build_pieces()

    def _corner_time(self, k: int) -> float:
        speed = float(self.junction_speeds_m_s[k])
        return corner_time_s(speed, self._changes[k], self._axes) if speed > 0.0 else 0.0

    def _corner_caps_m_s(self, tolerance_m: float) -> FloatArray:
        segments, dwell = self.program.segments, self.program.junction_dwell_s
        caps = np.zeros(len(segments) + 1)
        for k in range(1, len(segments)):
            before, after = segments[k - 1], segments[k]
            if isinstance(before, ArcSegment) or isinstance(after, ArcSegment) or dwell[k] > 0.0:
                continue
            u1, u2 = before.unit_vector, after.unit_vector
            turn = math.acos(min(max(float(np.dot(u1, u2)), -1.0), 1.0))
            cap = corner_speed_m_s(turn, self._changes[k], 0.5 * min(before.length_m, after.length_m),
                                   tolerance_m, self._axes)
            caps[k] = min(cap, self.path_limits[k - 1].speed_m_s, self.path_limits[k].speed_m_s)
        return caps

    def _junction_speeds(self, tolerance_m: float) -> FloatArray:
        """Corner caps lowered so that each piece can change from one junction's speed to the next's."""
        speeds = self._corner_caps_m_s(tolerance_m)
        self.junction_speeds_m_s = speeds
        trims = [self._corner_time(k) * 0.5 * float(speeds[k]) for k in range(len(speeds))]
        room = [seg.length_m - trims[k] - trims[k + 1] for k, seg in enumerate(self.program.segments)]
        for k in range(len(room) - 1, -1, -1):
            p = self.path_limits[k]
            speeds[k] = reachable_m_s(float(speeds[k + 1]), room[k], float(speeds[k]), p.accel_m_s2, p.jerk_m_s3)
        for k in range(len(room)):
            p = self.path_limits[k]
            speeds[k + 1] = reachable_m_s(float(speeds[k]), room[k], float(speeds[k + 1]), p.accel_m_s2,
                                          p.jerk_m_s3)
        return speeds

    def _build_pieces(self) -> None:
        """Start time, duration, kind (0: a segment's S-curve, 1: a corner) and index of every piece."""
        dwell, t = self.program.junction_dwell_s, 0.0
        self.corners: dict[int, Corner] = {}
        pieces: list[tuple[float, int, int]] = []
        for k, curve in enumerate(self.curves):
            t += float(dwell[k])
            duration = self._corner_times[k]
            if duration > 0.0:
                self.corners[k] = Corner(self.program.segments[k].start_m, self._tangents[k - 1][1],
                                         self._tangents[k][0], float(self.junction_speeds_m_s[k]), duration)
                pieces.append((t, 1, k))
                t += duration
            pieces.append((t, 0, k))
            t += curve.duration_s
        self._piece_start_s = np.array([p[0] for p in pieces])
        self._piece_kind, self._piece_index = np.array([p[1] for p in pieces]), np.array([p[2] for p in pieces])
        self._end_s = t + float(dwell[-1])

    @property
    def duration_s(self) -> float:
        """The plan's duration, s (the last dwell included)."""
        return self._end_s

    @property
    def peak_speed_m_s(self) -> FloatArray:
        """Each segment's peak path speed, m/s, ``(n_segments,)``."""
        return np.array([curve.peak_m_s for curve in self.curves])

    def axis_arrays(self, times_s: ArrayLike) -> tuple[NDArray[np.intp], FloatArray, FloatArray, FloatArray,
                                                      FloatArray, FloatArray]:
        """Segment, local arc length (m), path speed (m/s) and axis position (m), velocity (m/s), acceleration
        (m/s²) ``(M, n_axes)`` at ``times_s`` (s). On a corner: the segment of its nearer half, and the programmed
        length at the same share of the corner."""
        t = np.asarray(times_s, dtype=float).reshape(-1)
        piece = np.clip(np.searchsorted(self._piece_start_s, t, side="right") - 1, 0, len(self._piece_start_s) - 1)
        n = self.program.n_axes
        index, s_local, speed = np.zeros(t.size, dtype=np.intp), np.zeros(t.size), np.zeros(t.size)
        position, velocity, acceleration = (np.zeros((t.size, n)) for _ in range(3))
        for p in np.unique(piece).tolist():
            rows = np.flatnonzero(piece == p)
            k, local = int(self._piece_index[p]), t[rows] - self._piece_start_s[p]
            if self._piece_kind[p] == 1:
                corner = self.corners[k]
                x, position[rows], velocity[rows], acceleration[rows] = corner.evaluate(local)
                first = x < 0.5
                index[rows] = np.where(first, k - 1, k)
                s_local[rows] = np.where(first, self.program.segments[k - 1].length_m, 0.0) \
                    + corner.trim_m * (2.0 * x - 1.0)
                speed[rows] = np.linalg.norm(velocity[rows], axis=1)
                continue
            s, v, a, _ = self.curves[k].evaluate(local)
            segment = self.program.segments[k]
            s = np.clip(s + self._trims[k], 0.0, segment.length_m)
            tangent = segment.tangent(s)
            index[rows], s_local[rows], speed[rows] = k, s, v
            position[rows], velocity[rows] = segment.point(s), v[:, None] * tangent
            acceleration[rows] = a[:, None] * tangent + (v * v)[:, None] * segment.curvature_vector(s)
        return index, s_local, speed, position, velocity, acceleration


#: Shares of the path tolerance :func:`quickest_jerk_plan` plans with (0: every corner an exact stop).
TOLERANCE_SHARES = (1.0, 0.25, 0.0625, 0.0)


def quickest_jerk_plan(program: Program, limits: AxisLimits, clamp_feed: bool, tolerance_m: float) -> JerkPlan:
    """The quickest :class:`JerkPlan` at :data:`TOLERANCE_SHARES` of ``tolerance_m``: never slower than exact stop.

    A sharp corner passed at speed within a small tolerance can take longer than stopping there (its speed is
    low and its trim long); a smaller share passes it faster or stops.
    """
    plans = [JerkPlan(program, limits, clamp_feed, share * tolerance_m)
             for share in (TOLERANCE_SHARES if tolerance_m > 0.0 else (0.0,))]
    return min(plans, key=lambda plan: plan.duration_s)
