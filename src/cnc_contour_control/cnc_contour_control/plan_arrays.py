"""The feed-profile planner's per-segment quantities over whole programs at once (NumPy).

:mod:`cnc_contour_control.interpolation` plans one speed profile over every
segment of a program. What it needs per segment (the largest ``|T_j|`` and
``|K_j|`` over the segment, the cruise speed and tangential acceleration that
keep every axis within its limits, the constant-acceleration phases) is
computed here for all segments in one pass each, with the formulas of
:meth:`ArcSegment.max_abs_tangent`, :meth:`ArcSegment.max_abs_curvature_per_m`,
:func:`cnc_contour_control.arc_budget.combined_tangential_m_s2` and the
trapezoid of :func:`profile_phases`. Only the backward/forward pass over the
junction speeds (:func:`junction_speeds_m_s`) is a loop: each junction's speed
depends on the next one's.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.arc import ArcSegment
from cnc_contour_control.arc_budget import combined_tangential_rows
from cnc_contour_control.errors import ProgramError
from cnc_contour_control.geometry import Segment, segment_label
from cnc_contour_control.points import FloatArray
from cnc_contour_control.units import m_s_to_mm_min

_MIN_TANGENT = 1.0e-12
_HALF_PI = 0.5 * math.pi


@dataclass(frozen=True)
class SegmentExtents:
    """Per segment ``(N, n_axes)``: largest ``|T_j|`` and ``|K_j|`` (1/m); per arc (rows ``arcs``) the rest.

    ``kappa_per_m`` is ``R (sweep / length)**2``, ``rate`` is ``R sweep / length`` and ``in_plane`` marks each
    arc's two plane axes, all in the order of ``arcs`` (indices into the segments).
    """

    tangent: FloatArray
    curvature_per_m: FloatArray
    arcs: NDArray[np.intp]
    kappa_per_m: FloatArray
    rate: FloatArray
    in_plane: NDArray[np.bool_]


def max_abs_cos(low_rad: FloatArray, high_rad: FloatArray) -> FloatArray:
    """Largest ``|cos θ|`` for θ in ``[low_rad, high_rad]``, elementwise (``points.max_abs_cos``)."""
    reaches_peak = np.ceil(low_rad / math.pi) * math.pi <= high_rad
    return np.where(reaches_peak, 1.0, np.maximum(np.abs(np.cos(low_rad)), np.abs(np.cos(high_rad))))


def segment_extents(segments: Sequence[Segment], n_axes: int) -> SegmentExtents:
    """Largest ``|T_j|`` and ``|K_j|`` of every segment (lines: ``|unit|`` and 0; arcs as their methods)."""
    arc_flags = np.array([isinstance(segment, ArcSegment) for segment in segments], dtype=bool)
    arcs = np.flatnonzero(arc_flags)
    tangent, curvature = np.zeros((len(segments), n_axes)), np.zeros((len(segments), n_axes))
    lines = np.flatnonzero(~arc_flags)
    if lines.size:
        tangent[lines] = np.abs(np.array([segments[i].unit_vector for i in lines.tolist()]))
    chosen = [segments[i] for i in arcs.tolist()]
    radius, sweep, length = (np.array([getattr(arc, name) for arc in chosen], dtype=float)
                             for name in ("radius_m", "sweep_rad", "length_m"))
    start = np.array([arc.start_angle_rad for arc in chosen], dtype=float)
    end = start + np.array([arc.direction for arc in chosen], dtype=float) * sweep
    low, high = np.minimum(start, end), np.maximum(start, end)
    rate, kappa = radius * sweep / length, radius * (sweep / length) ** 2
    plane = np.array([arc.plane for arc in chosen], dtype=np.intp).reshape(len(chosen), 2)
    rows = np.arange(len(chosen))
    if chosen:
        arc_tangent = np.abs(np.array([arc.rise_m for arc in chosen])) / length[:, None]
        arc_curvature = np.zeros_like(arc_tangent)
        arc_tangent[rows, plane[:, 0]] = rate * max_abs_cos(low - _HALF_PI, high - _HALF_PI)
        arc_tangent[rows, plane[:, 1]] = rate * max_abs_cos(low, high)
        arc_curvature[rows, plane[:, 0]] = kappa * max_abs_cos(low, high)
        arc_curvature[rows, plane[:, 1]] = kappa * max_abs_cos(low - _HALF_PI, high - _HALF_PI)
        tangent[arcs], curvature[arcs] = arc_tangent, arc_curvature
    in_plane = np.zeros((len(chosen), n_axes), dtype=bool)
    in_plane[rows, plane[:, 0]] = in_plane[rows, plane[:, 1]] = True
    return SegmentExtents(tangent, curvature, arcs, kappa, rate, in_plane)


def min_ratio(budget: FloatArray, usage: FloatArray) -> FloatArray:
    """``min_j budget_j / usage_j`` per row over the axes with ``usage_j > 1e-12`` (inf if none); ``(N,)``."""
    used = usage > _MIN_TANGENT
    budget = np.broadcast_to(budget, usage.shape)
    return np.divide(budget, usage, out=np.full(usage.shape, math.inf), where=used).min(axis=1)


def _refuse_feeds(segments: Sequence[Segment], feed: FloatArray, axis_speed: FloatArray, first_index: int) -> None:
    over = np.flatnonzero(feed > axis_speed * (1.0 + 1e-12))
    if over.size:
        i = int(over[0])
        raise ProgramError(
            f"{segment_label(i + first_index, segments[i])}: feed_mm_min must be <= {m_s_to_mm_min(axis_speed[i]):.6g} "
            f"(axis velocity limits along the segment), got {m_s_to_mm_min(feed[i]):.6g}")


def plan_limits(segments: Sequence[Segment], max_velocity_m_s: FloatArray, max_acceleration_m_s2: FloatArray,
                centripetal_fraction: float, combined_budget: bool, clamp_feed: bool,
                first_index: int = 0) -> tuple[FloatArray, FloatArray]:
    """Cruise speed (m/s) and tangential acceleration (m/s²) of every segment, ``(N,)`` each.

    The speed keeps ``v |T_j| <= vmax_j`` and, on arcs, ``v² |K_j| <= f amax_j``; the acceleration
    ``|a_t T_j| <= (1 - f) amax_j`` (``f`` = ``centripetal_fraction`` on curved segments, else 0), or on
    arcs with ``combined_budget`` the larger bound of :mod:`cnc_contour_control.arc_budget`.

    Raises
    ------
    ProgramError
        If a programmed feed exceeds the axis velocity limits and ``clamp_feed`` is False (the first such
        segment, numbered from ``first_index``).
    """
    velocity, acceleration = np.asarray(max_velocity_m_s, float), np.asarray(max_acceleration_m_s2, float)
    extents = segment_extents(segments, velocity.size)
    feed = np.array([segment.feed_m_s for segment in segments], dtype=float)
    axis_speed = min_ratio(velocity[None, :], extents.tangent)
    if not clamp_feed:
        _refuse_feeds(segments, feed, axis_speed, first_index)
    fraction = np.where(extents.curvature_per_m.any(axis=1), centripetal_fraction, 0.0)
    centripetal = np.sqrt(min_ratio(fraction[:, None] * acceleration, extents.curvature_per_m))
    speed = np.minimum(np.minimum(feed, axis_speed), np.where(fraction > 0.0, centripetal, math.inf))
    accel = min_ratio((1.0 - fraction)[:, None] * acceleration, extents.tangent)
    if combined_budget and extents.arcs.size:
        arcs = extents.arcs
        accel[arcs] = combined_tangential_rows(extents.kappa_per_m, extents.rate, extents.in_plane, speed[arcs],
                                               acceleration, extents.tangent[arcs], extents.curvature_per_m[arcs])
    return speed, accel


def junction_speeds_m_s(cruise_m_s: FloatArray, accel_m_s2: FloatArray, length_m: FloatArray,
                        smooth: NDArray[np.bool_]) -> FloatArray:
    """Speed at every junction (m/s, ``(N + 1,)``): the smaller cruise speed at ``smooth`` inner junctions, else 0,
    lowered so that each segment can brake into and accelerate out of it (``v² <= v_next² + 2 a L``).
    """
    cruise = np.asarray(cruise_m_s, dtype=float)
    speeds = [0.0, *np.where(smooth, np.minimum(cruise[:-1], cruise[1:]), 0.0).tolist(), 0.0]
    reach = (2.0 * np.asarray(accel_m_s2, dtype=float) * np.asarray(length_m, dtype=float)).tolist()
    sqrt = math.sqrt
    for k in range(len(reach) - 1, -1, -1):
        speeds[k] = min(speeds[k], sqrt(speeds[k + 1] ** 2 + reach[k]))
    for k in range(len(reach)):
        speeds[k + 1] = min(speeds[k + 1], sqrt(speeds[k] ** 2 + reach[k]))
    return np.array(speeds)


@dataclass(frozen=True)
class Phases:
    """Constant-acceleration phases in time order, each array ``(P,)``.

    ``start_s`` is each phase's start time (s, ``(P + 1,)``: the last entry is the profile's duration),
    ``s0_m`` where it starts along its segment (m), ``v0_m_s`` its start speed, ``accel_m_s2`` its
    path acceleration and ``segment`` its segment index.
    """

    start_s: FloatArray
    s0_m: FloatArray
    v0_m_s: FloatArray
    accel_m_s2: FloatArray
    segment: NDArray[np.intp]


def profile_phases(length_m: FloatArray, entry_m_s: FloatArray, exit_m_s: FloatArray, cruise_m_s: FloatArray,
                   accel_m_s2: FloatArray, dwell_s: FloatArray) -> Phases:
    """Accelerate / cruise / decelerate phases of every segment, with the dwells as phases at rest.

    Parameters
    ----------
    length_m, entry_m_s, exit_m_s, cruise_m_s, accel_m_s2 : ndarray, shape (N,)
        Per segment: length (m), speed at its start and end (m/s), cruise speed (m/s), tangential
        acceleration (m/s², > 0).
    dwell_s : ndarray, shape (N + 1,)
        Dwell per junction (s; index k: before segment k, N: the program's end).

    Returns
    -------
    Phases
        Phases with a positive duration: per segment its dwell before, accelerate, cruise, decelerate,
        and after the last one the end's dwell.
    """
    length, entry, exit_, accel = (np.asarray(v, dtype=float) for v in (length_m, entry_m_s, exit_m_s, accel_m_s2))
    n = length.size
    peak_sq = np.minimum(np.asarray(cruise_m_s, dtype=float) ** 2, accel * length + 0.5 * (entry ** 2 + exit_ ** 2))
    peak = np.maximum(np.maximum(np.sqrt(peak_sq), entry), exit_)
    accel_len = (peak ** 2 - entry ** 2) / (2.0 * accel)
    decel_len = (peak ** 2 - exit_ ** 2) / (2.0 * accel)
    cruise_len = np.maximum(length - accel_len - decel_len, 0.0)
    dwell = np.asarray(dwell_s, dtype=float)
    after = np.zeros(n)
    after[-1] = dwell[-1]
    zeros = np.zeros(n)
    table = {  # per segment, five phases in time order: (s0, v0, accel, duration)
        "s0": np.stack([zeros, zeros, accel_len, accel_len + cruise_len, length], axis=1),
        "v0": np.stack([zeros, entry, peak, peak, zeros], axis=1),
        "accel": np.stack([zeros, accel, zeros, -accel, zeros], axis=1),
        "duration": np.stack([dwell[:-1], (peak - entry) / accel, cruise_len / peak, (peak - exit_) / accel, after],
                             axis=1)}
    keep = (table["duration"] > 0.0).ravel()
    start = np.concatenate(([0.0], np.cumsum(table["duration"].ravel()[keep])))
    segment = np.repeat(np.arange(n, dtype=np.intp), 5)[keep]
    return Phases(start, table["s0"].ravel()[keep], table["v0"].ravel()[keep], table["accel"].ravel()[keep], segment)
