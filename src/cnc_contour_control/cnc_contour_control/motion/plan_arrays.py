"""The feed-profile planner's per-segment quantities over whole programs at once (NumPy).

:mod:`cnc_contour_control.motion.interpolation` plans one speed profile over every
segment of a program. What it needs per segment (the largest ``|T_j|`` and
``|K_j|`` over the segment, the cruise speed and tangential acceleration that
keep every axis within its limits, the constant-acceleration phases) is
computed here for all segments in one pass each, with the formulas of
:meth:`ArcSegment.max_abs_tangent`, :meth:`ArcSegment.max_abs_curvature_per_m`,
:func:`cnc_contour_control.motion.arc_budget.combined_tangential_m_s2` and the
trapezoid of :func:`profile_phases`. Only the backward/forward pass over the
junction speeds (:func:`junction_speeds_m_s`) is a loop: each junction's speed
depends on the next one's.

With speed bands (:class:`SpeedBands`, arcs under the combined budget:
:func:`cnc_contour_control.motion.arc_budget.speed_bands`) a segment's tangential
acceleration is constant within each band of speeds and larger in lower
bands; the distance to change speed is then a sum over the bands
(:meth:`SpeedBands.distance_m`), and each accelerate or decelerate phase
becomes one phase per band it crosses (:func:`banded_phases`). One band of
``[0, V]`` is the trapezoid.
"""
from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.core.units import m_s_to_mm_min
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.arc_budget import combined_tangential_rows, speed_bands
from cnc_contour_control.motion.geometry import LineSegment, Program, Segment, segment_label
from cnc_contour_control.motion.points import FloatArray
from cnc_contour_control.motion.segment_tangents import junction_turns_rad

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
        tangent[lines] = np.abs(np.array([cast(LineSegment, segments[i]).unit_vector for i in lines.tolist()]))
    chosen = [cast(ArcSegment, segments[i]) for i in arcs.tolist()]
    radius, sweep, length = (np.array([getattr(arc, name) for arc in chosen], dtype=float)
                             for name in ("radius_m", "sweep_rad", "length_m"))
    start = np.array([arc.start_angle_rad for arc in chosen], dtype=np.float64)
    end = start + np.array([arc.direction for arc in chosen], dtype=np.float64) * sweep
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


def plan_banded_limits(segments: Sequence[Segment], max_velocity_m_s: FloatArray, max_acceleration_m_s2: FloatArray,
                       centripetal_fraction: float, combined_budget: bool, clamp_feed: bool,
                       first_index: int = 0, n_bands: int = 1) -> tuple[FloatArray, FloatArray, SpeedBands]:
    """Cruise speed (m/s), tangential acceleration at the cruise speed (m/s²), ``(N,)`` each, and speed bands.

    The speed keeps ``v |T_j| <= vmax_j`` and, on arcs, ``v² |K_j| <= f amax_j``; the acceleration
    ``|a_t T_j| <= (1 - f) amax_j`` (``f`` = ``centripetal_fraction`` on curved segments, else 0), or on
    arcs with ``combined_budget`` the larger bound of :mod:`cnc_contour_control.motion.arc_budget`.

    Raises
    ------
    ProgramError
        If a programmed feed exceeds the axis velocity limits and ``clamp_feed`` is False (the first such
        segment, numbered from ``first_index``).

    Notes
    -----
    With ``combined_budget`` and ``n_bands`` > 1 the arcs' bands are those of
    :func:`~cnc_contour_control.motion.arc_budget.speed_bands`; every other segment has one band ``[0, V]`` at its
    tangential acceleration.
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
    banded = combined_budget and extents.arcs.size > 0
    if banded:
        arcs = extents.arcs
        accel[arcs] = combined_tangential_rows(extents.kappa_per_m, extents.rate, extents.in_plane, speed[arcs],
                                               acceleration, extents.tangent[arcs], extents.curvature_per_m[arcs])
    bands = SpeedBands.single(speed, accel, n_bands if banded else 1)
    if banded and n_bands > 1:
        edges, band_accel = speed_bands(extents.kappa_per_m, extents.rate, extents.in_plane, speed[extents.arcs],
                                        acceleration, extents.tangent[extents.arcs],
                                        extents.curvature_per_m[extents.arcs], n_bands)
        bands.edges_m_s[extents.arcs], bands.accel_m_s2[extents.arcs] = edges, band_accel
    return speed, accel, bands


@dataclass(frozen=True)
class SpeedBands:
    """Per segment, bands of speed with a constant tangential acceleration each.

    ``edges_m_s`` ``(N, K + 1)``: band edges from 0 to the cruise speed, m/s (a segment with one band has
    ``[0, ..., 0, V]``: empty bands first); ``accel_m_s2`` ``(N, K)``: tangential acceleration in each band,
    m/s², not increasing with the band.
    """

    edges_m_s: FloatArray
    accel_m_s2: FloatArray

    @classmethod
    def single(cls, cruise_m_s: FloatArray, accel_m_s2: FloatArray, n_bands: int = 1) -> SpeedBands:
        """One band ``[0, V]`` per segment at its acceleration, as the last of ``n_bands`` columns."""
        cruise, accel = np.asarray(cruise_m_s, dtype=float), np.asarray(accel_m_s2, dtype=float)
        edges = np.zeros((cruise.size, n_bands + 1))
        edges[:, -1] = cruise
        return cls(edges, np.repeat(accel[:, None], n_bands, axis=1))

    @property
    def n_bands(self) -> int:
        """Bands per segment (K)."""
        return int(self.accel_m_s2.shape[1])

    def pieces_m(self, low_m_s: FloatArray, high_m_s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Per band, the part of ``[low, high]`` in it (m/s) and the distance to cross it (m); ``(N, K)`` each."""
        low_edge, high_edge = self.edges_m_s[:, :-1], self.edges_m_s[:, 1:]
        low = np.clip(np.asarray(low_m_s, dtype=float)[:, None], low_edge, high_edge)
        high = np.clip(np.asarray(high_m_s, dtype=float)[:, None], low_edge, high_edge)
        return low, high, (high * high - low * low) / (2.0 * self.accel_m_s2)

    def distance_m(self, low_m_s: FloatArray, high_m_s: FloatArray) -> FloatArray:
        """Distance to change speed between ``low`` and ``high`` (m/s, ``(N,)``, within the bands), m."""
        return self.pieces_m(low_m_s, high_m_s)[2].sum(axis=1)

    def speed_m_s(self, distance_m: FloatArray) -> FloatArray:
        """Speed reached from rest over ``distance_m`` (``(N,)``, m), at most the cruise speed, m/s."""
        reach = np.concatenate([np.zeros((self.edges_m_s.shape[0], 1)),
                                np.cumsum(self.pieces_m(np.zeros(len(self.edges_m_s)), self.edges_m_s[:, -1])[2],
                                          axis=1)], axis=1)
        distance = np.minimum(np.asarray(distance_m, dtype=float), reach[:, -1])
        band = np.minimum(np.count_nonzero(reach[:, 1:-1] <= distance[:, None], axis=1), self.n_bands - 1)
        rows = np.arange(band.size)
        low = self.edges_m_s[rows, band]
        return np.sqrt(low * low + 2.0 * self.accel_m_s2[rows, band] * (distance - reach[rows, band]))


def junction_caps_m_s(cruise_m_s: FloatArray, smooth: NDArray[np.bool_],
                      window_cap_m_s: FloatArray | None = None, entry_m_s: float = 0.0) -> list[float]:
    """Largest speed at every junction before the passes (m/s, ``N + 1``): the smaller cruise speed at ``smooth``
    inner junctions, else 0 (``entry_m_s`` at the first), and at most ``window_cap_m_s``
    (:func:`look_ahead_caps_m_s`) if given."""
    cruise = np.asarray(cruise_m_s, dtype=float)
    caps = np.concatenate(([entry_m_s], np.where(smooth, np.minimum(cruise[:-1], cruise[1:]), 0.0), [0.0]))
    return (caps if window_cap_m_s is None else np.minimum(caps, window_cap_m_s)).tolist()


def look_ahead_caps_m_s(accel_m_s2: FloatArray, length_m: FloatArray, window_segments: int) -> FloatArray:
    """Speed at each junction from which the next ``window_segments`` segments can brake to rest, m/s, ``(N + 1,)``.

    A look-ahead buffer of ``W`` segments sees, at junction ``j``, segments ``j .. j + W - 1`` and must be able
    to stop at the end of the last: ``v_j² <= sum 2 a_i L_i`` over them (``accel_m_s2``: each segment's lowest
    tangential acceleration, so the bound holds for banded segments too). inf where the window reaches the
    program's end (the end's stop is then planned as is).
    """
    reach = np.concatenate(([0.0], np.cumsum(2.0 * np.asarray(accel_m_s2, float) * np.asarray(length_m, float))))
    n, caps = reach.size - 1, np.full(reach.size, math.inf)
    ahead = np.arange(max(n - window_segments + 1, 0))
    caps[ahead] = np.sqrt(np.maximum(reach[ahead + window_segments] - reach[ahead], 0.0))
    return caps


def junction_speeds_m_s(cruise_m_s: FloatArray, accel_m_s2: FloatArray, length_m: FloatArray,
                        smooth: NDArray[np.bool_], window_cap_m_s: FloatArray | None = None,
                        entry_m_s: float = 0.0) -> FloatArray:
    """Speed at every junction (m/s, ``(N + 1,)``): the caps of :func:`junction_caps_m_s`, lowered so that each
    segment can brake into and accelerate out of it (``v² <= v_next² + 2 a L``).

    The first junction's speed is ``entry_m_s`` (0: a start at rest; a streaming plan's chunk starts at the speed
    the previous chunk committed, :mod:`cnc_contour_control.motion.plan_stream`); the last one's is a stop.
    """
    speeds = junction_caps_m_s(cruise_m_s, smooth, window_cap_m_s, entry_m_s)
    reach = (2.0 * np.asarray(accel_m_s2, dtype=float) * np.asarray(length_m, dtype=float)).tolist()
    sqrt = math.sqrt
    for k in range(len(reach) - 1, -1, -1):
        speeds[k] = min(speeds[k], sqrt(speeds[k + 1] ** 2 + reach[k]))
    speeds[0] = entry_m_s
    for k in range(len(reach)):
        speeds[k + 1] = min(speeds[k + 1], sqrt(speeds[k] ** 2 + reach[k]))
    return np.array(speeds)


def banded_junction_speeds_m_s(cruise_m_s: FloatArray, bands: SpeedBands, length_m: FloatArray,
                               smooth: NDArray[np.bool_], window_cap_m_s: FloatArray | None = None,
                               entry_m_s: float = 0.0) -> FloatArray:
    """:func:`junction_speeds_m_s` with speed bands: each segment can brake into and accelerate out of its junctions.

    Each step first takes the trapezoid's ``sqrt(v_next² + 2 a L)`` with the segment's lowest acceleration (its
    top band's); only where that falls short of the junction's cap does a banded segment compute the speed its
    bands reach (:class:`_Reach`, never less), so the result is the banded one at the trapezoid's cost where
    the cap holds.
    """
    if bands.n_bands == 1:
        return junction_speeds_m_s(cruise_m_s, bands.accel_m_s2[:, 0], length_m, smooth, window_cap_m_s, entry_m_s)
    length = np.asarray(length_m, dtype=float)
    speeds = junction_caps_m_s(cruise_m_s, smooth, window_cap_m_s, entry_m_s)
    single = (2.0 * bands.accel_m_s2[:, -1] * length).tolist()
    banded, reach, sqrt = (bands.edges_m_s[:, -2] > 0.0).tolist(), _Reach(bands, length), math.sqrt
    for k in range(len(single) - 1, -1, -1):
        step = sqrt(speeds[k + 1] ** 2 + single[k])
        speeds[k] = min(speeds[k], reach(k, speeds[k + 1]) if step < speeds[k] and banded[k] else step)
    speeds[0] = entry_m_s
    for k in range(len(single)):
        step = sqrt(speeds[k] ** 2 + single[k])
        speeds[k + 1] = min(speeds[k + 1], reach(k, speeds[k]) if step < speeds[k + 1] and banded[k] else step)
    return np.array(speeds)


def program_junction_speeds_m_s(program: Program, cruise_m_s: FloatArray, bands: SpeedBands, tolerance_rad: float,
                                look_ahead_segments: int | None = None) -> FloatArray:
    """:func:`banded_junction_speeds_m_s` over ``program``: stops at dwells and at turns over ``tolerance_rad``,
    the look-ahead caps of a window of ``look_ahead_segments`` if shorter than the program; ``(N + 1,)``, m/s."""
    smooth = (junction_turns_rad(program.segments) <= tolerance_rad) & (program.junction_dwell_s[1:-1] == 0.0)
    lengths = np.array([segment.length_m for segment in program.segments])
    window = None
    if look_ahead_segments is not None and look_ahead_segments < len(lengths):
        window = look_ahead_caps_m_s(bands.accel_m_s2[:, -1], lengths, look_ahead_segments)
    return banded_junction_speeds_m_s(cruise_m_s, bands, lengths, smooth, window)


class _Reach:
    """``reach(k, v)``: the speed segment ``k``'s bands reach from ``v`` over its length (m/s, unbounded above)."""

    def __init__(self, bands: SpeedBands, length_m: FloatArray) -> None:
        self._bands, self._length_m = bands, length_m
        self._rows: dict[int, tuple[list[float], list[float], list[float], float]] = {}

    def _row(self, k: int) -> tuple[list[float], list[float], list[float], float]:
        if k not in self._rows:
            edges, accel = self._bands.edges_m_s[k], self._bands.accel_m_s2[k]
            reach = np.concatenate(([0.0], np.cumsum((edges[1:] ** 2 - edges[:-1] ** 2) / (2.0 * accel))))
            self._rows[k] = edges.tolist(), accel.tolist(), reach.tolist(), float(self._length_m[k])
        return self._rows[k]

    def __call__(self, k: int, speed_m_s: float) -> float:
        edges, accel, reach, length_m = self._row(k)
        band = min(max(bisect.bisect_right(edges, speed_m_s) - 1, 0), len(accel) - 1)
        distance = reach[band] + (speed_m_s * speed_m_s - edges[band] ** 2) / (2.0 * accel[band]) + length_m
        band = min(bisect.bisect_right(reach, distance) - 1, len(accel) - 1)
        return math.sqrt(edges[band] ** 2 + 2.0 * accel[band] * (distance - reach[band]))


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
    return _phases_from_table(table)


def banded_phases(length_m: FloatArray, entry_m_s: FloatArray, exit_m_s: FloatArray, cruise_m_s: FloatArray,
                  bands: SpeedBands, dwell_s: FloatArray) -> Phases:
    """:func:`profile_phases` with speed bands: accelerate and decelerate one phase per band crossed.

    Parameters
    ----------
    length_m, entry_m_s, exit_m_s, cruise_m_s : ndarray, shape (N,)
        As :func:`profile_phases`.
    bands : SpeedBands
        Each segment's bands (one band: exactly :func:`profile_phases`).
    dwell_s : ndarray, shape (N + 1,)
        Dwell per junction, s.

    Returns
    -------
    Phases
        Per segment its dwell, the accelerating bands upward, cruise, the decelerating bands downward, and
        after the last segment the end's dwell; phases with a positive duration only.
    """
    if bands.n_bands == 1:
        return profile_phases(length_m, entry_m_s, exit_m_s, cruise_m_s, bands.accel_m_s2[:, 0], dwell_s)
    length, entry, exit_ = (np.asarray(v, dtype=float) for v in (length_m, entry_m_s, exit_m_s))
    rest = np.zeros_like(entry)
    half = 0.5 * (length + bands.distance_m(rest, entry) + bands.distance_m(rest, exit_))
    peak = np.maximum(np.maximum(bands.speed_m_s(half), entry), exit_)
    up_low, up_high, up_m = bands.pieces_m(entry, peak)
    down_low, down_high, down_m = (piece[:, ::-1] for piece in bands.pieces_m(exit_, peak))
    accel = bands.accel_m_s2
    up_s0 = np.cumsum(up_m, axis=1) - up_m
    cruise_len = np.maximum(length - up_m.sum(axis=1) - down_m.sum(axis=1), 0.0)
    down_s0 = (up_m.sum(axis=1) + cruise_len)[:, None] + np.cumsum(down_m, axis=1) - down_m
    dwell, zeros = np.asarray(dwell_s, dtype=float), np.zeros((length.size, 1))
    after = np.zeros((length.size, 1))
    after[-1, 0] = dwell[-1]
    table = {  # per segment, 2 K + 3 phases in time order
        "s0": np.hstack([zeros, up_s0, _column(up_m.sum(axis=1)), down_s0, _column(length)]),
        "v0": np.hstack([zeros, up_low, _column(peak), down_high, zeros]),
        "accel": np.hstack([zeros, accel, zeros, -accel[:, ::-1], zeros]),
        "duration": np.hstack([_column(dwell[:-1]), (up_high - up_low) / accel, _column(cruise_len / peak),
                               (down_high - down_low) / accel[:, ::-1], after])}
    return _phases_from_table(table)


def _column(values: FloatArray) -> FloatArray:
    return np.asarray(values, dtype=float)[:, None]


def _phases_from_table(table: dict[str, FloatArray]) -> Phases:
    """The phases of a ``(N, width)`` table (``s0``, ``v0``, ``accel``, ``duration``) in row-major time order."""
    n, width = table["duration"].shape
    keep = (table["duration"] > 0.0).ravel()
    start = np.concatenate(([0.0], np.cumsum(table["duration"].ravel()[keep])))
    segment = np.repeat(np.arange(n, dtype=np.intp), width)[keep]
    return Phases(start, table["s0"].ravel()[keep], table["v0"].ravel()[keep], table["accel"].ravel()[keep], segment)
