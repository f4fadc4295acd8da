"""Per corner, a blend or an exact stop: whichever the planner runs faster.

Without jerk limits a blend is not always quicker than stopping. A blend arc
of radius ``R`` trims ``d`` from each neighbour and is run at most at
``v_b = sqrt(f amax R)``; a stop reaches ``sqrt(2 a x)`` at distance ``x``
from the corner. Where ``v_b² < 2 a d`` (sharp turns: ``d = R tan(θ/2)``) the
blend brakes further ahead than the stop does and can take longer, and more so
the larger ``R``.

Each corner is judged on its own (so that a streaming plan, which blends the
program in chunks, chooses as the whole plan does): the region from the middle
of the segment before to the middle of the segment after, entered and left at
the same speeds in both cases (the fastest both allow), is timed with the
trapezoidal profile of each case (each piece from its entry to its exit speed
under its cruise speed and tangential acceleration, the junction speeds by a
backward and a forward pass as the planner's; the blend arc at most at ``v_b``
with ``(1 - f) amax``, lower bounds of the planner's). The blend is kept where
it is faster. Only the largest blend within the tolerance is timed: timing
smaller ones too picked smaller arcs on dense CAM code, whose corners the model
times as if both neighbours stopped (a spiral pocket took 26 % longer).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.motion.blend_table import BlendTable
from cnc_contour_control.motion.geometry import Segment
from cnc_contour_control.motion.plan_arrays import plan_banded_limits
from cnc_contour_control.motion.points import FloatArray


@dataclass(frozen=True)
class CornerLimits:
    """What the choice between a blend and a stop needs of the planner.

    ``max_velocity_m_s`` and ``max_acceleration_m_s2``: per axis, m/s and m/s², shape ``(n_axes,)``;
    ``centripetal_fraction``: the share of each axis's acceleration given to centripetal use on arcs.
    """

    max_velocity_m_s: FloatArray
    max_acceleration_m_s2: FloatArray
    centripetal_fraction: float


def piece_time_s(length_m: FloatArray, entry_m_s: FloatArray, exit_m_s: FloatArray, cruise_m_s: FloatArray,
                 accel_m_s2: FloatArray) -> FloatArray:
    """Time (s) of the trapezoidal profile over each piece, from entry to exit speed under the cruise speed.

    All arrays ``(M,)``: length (m, >= 0), speeds (m/s; entry and exit reachable from each other over the
    length), acceleration (m/s², > 0).
    """
    length = np.maximum(length_m, 0.0)
    peak = np.sqrt(np.minimum(cruise_m_s ** 2, accel_m_s2 * length + 0.5 * (entry_m_s ** 2 + exit_m_s ** 2)))
    peak = np.maximum(np.maximum(peak, entry_m_s), exit_m_s)
    ramps = (2.0 * peak * peak - entry_m_s ** 2 - exit_m_s ** 2) / (2.0 * accel_m_s2)
    cruise = np.divide(np.maximum(length - ramps, 0.0), peak, out=np.zeros_like(peak), where=peak > 0.0)
    return (2.0 * peak - entry_m_s - exit_m_s) / accel_m_s2 + cruise


def _neighbour_limits(segments: Sequence[Segment], limits: CornerLimits) -> tuple[FloatArray, FloatArray]:
    """Cruise speed (m/s) and tangential acceleration (m/s²) of ``segments`` as the planner sets them."""
    speed, accel, _ = plan_banded_limits(segments, limits.max_velocity_m_s, limits.max_acceleration_m_s2,
                                         limits.centripetal_fraction, False, True)
    return speed, accel


def blend_speed_m_s(table: BlendTable, feed_m_s: FloatArray, limits: CornerLimits) -> FloatArray:
    """A lower bound of the planner's cruise speed on each blend arc, m/s, ``(M,)``.

    The arc's feed (the smaller of its neighbours'), the velocity limits of its plane's axes, and
    ``v² / R <= f amax_j`` on both of them (an axis's curvature never exceeds ``1 / R``); for a blend of
    several pieces every axis's limits and ``R`` the pieces' in-plane radius.
    """
    vmax, amax = _blend_axes_min(table, limits.max_velocity_m_s), _blend_axes_min(table, limits.max_acceleration_m_s2)
    return np.minimum(np.minimum(feed_m_s, vmax), np.sqrt(limits.centripetal_fraction * amax * table.radius_m))


def corner_times_s(segments: Sequence[Segment], table: BlendTable, limits: CornerLimits, free: bool = False
                   ) -> tuple[FloatArray, FloatArray]:
    """Time (s, ``(M,)`` each) of each corner's region with its blend and with an exact stop instead.

    The region runs from the middle of the segment before to the middle of the one after, entered and left at
    the same speeds in both cases (the fastest both allow; with ``free`` the neighbours' cruise speeds, as
    between blended corners, where only the blend's time means anything). With the blend it is
    three pieces (the rest of the line before, the arc, the rest of the line after) whose junction speeds are
    planned as the planner does (a backward and a forward pass); the arc at most at :func:`blend_speed_m_s`
    with the split budget's tangential acceleration ``(1 - f) amax`` (lower bounds of the planner's).
    """
    k = table.junction
    speed, accel = _neighbour_limits([segments[i] for i in (k - 1).tolist()] + [segments[i] for i in k.tolist()],
                                     limits)
    v1, v2, a1, a2 = speed[:len(k)], speed[len(k):], accel[:len(k)], accel[len(k):]
    h1 = 0.5 * np.array([segments[i].length_m for i in (k - 1).tolist()])
    h2 = 0.5 * np.array([segments[i].length_m for i in k.tolist()])
    l1, l2 = np.maximum(h1 - table.trim_m, 0.0), np.maximum(h2 - table.trim_after_m, 0.0)
    feed = np.minimum([segments[i].feed_m_s for i in (k - 1).tolist()], [segments[i].feed_m_s for i in k.tolist()])
    vb = blend_speed_m_s(table, feed, limits)
    amax = _blend_axes_min(table, limits.max_acceleration_m_s2)
    ab, arc_m = (1.0 - limits.centripetal_fraction) * amax, _blend_length_m(table)
    u1, u2 = (v1, v2) if free else (np.minimum(v1, np.sqrt(2.0 * a1 * h1)), np.minimum(v2, np.sqrt(2.0 * a2 * h2)))
    w2 = np.minimum(vb, np.sqrt(u2 * u2 + 2.0 * a2 * l2))  # backward pass
    w1 = np.minimum(vb, np.sqrt(w2 * w2 + 2.0 * ab * arc_m))
    u1 = np.minimum(u1, np.sqrt(w1 * w1 + 2.0 * a1 * l1))
    w1 = np.minimum(w1, np.sqrt(u1 * u1 + 2.0 * a1 * l1))  # forward pass
    w2 = np.minimum(w2, np.sqrt(w1 * w1 + 2.0 * ab * arc_m))
    u2 = np.minimum(u2, np.sqrt(w2 * w2 + 2.0 * a2 * l2))
    zero = np.zeros_like(u1)
    stop_s = piece_time_s(h1, u1, zero, v1, a1) + piece_time_s(h2, zero, u2, v2, a2)
    blend_s = (piece_time_s(l1, u1, w1, v1, a1) + piece_time_s(arc_m, w1, w2, vb, ab)
               + piece_time_s(l2, w2, u2, v2, a2))
    return blend_s, stop_s


def slower_arcs(segments: Sequence[Segment], table: BlendTable, limits: CornerLimits) -> NDArray[np.bool_]:
    """Whether each blend arc's speed (:func:`blend_speed_m_s`) is below both neighbours' cruise speeds, ``(M,)``.

    Only there can a smaller arc be quicker between cruising neighbours.
    """
    k = table.junction
    speed, _ = _neighbour_limits([segments[i] for i in (k - 1).tolist()] + [segments[i] for i in k.tolist()], limits)
    feed = np.minimum([segments[i].feed_m_s for i in (k - 1).tolist()], [segments[i].feed_m_s for i in k.tolist()])
    lines_m_s = np.minimum(speed[:len(k)], speed[len(k):])
    return np.asarray(blend_speed_m_s(table, feed, limits) < lines_m_s * (1.0 - 1e-9), dtype=bool)


def faster_than_stop(segments: Sequence[Segment], table: BlendTable, limits: CornerLimits) -> NDArray[np.bool_]:
    """Whether each blend of ``table`` (corners of ``segments``) is quicker than an exact stop there, ``(M,)``."""
    if not len(table):
        return np.zeros(0, dtype=bool)
    blend_s, stop_s = corner_times_s(segments, table, limits)
    return np.asarray(blend_s < stop_s, dtype=bool)


def quickest_radius(segments: Sequence[Segment], candidates: Sequence[BlendTable], limits: CornerLimits
                    ) -> BlendTable:
    """Per corner, the candidate blend (rows of ``candidates``, in order of preference) whose region is quickest
    between cruising neighbours (:func:`corner_times_s` with ``free``); ties go to the earlier candidate."""
    timed = [(table, corner_times_s(segments, table, limits, free=True)[0]) for table in candidates if len(table)]
    if not timed:
        return candidates[0]
    junctions = np.unique(np.concatenate([table.junction for table, _ in timed]))
    best = np.full(junctions.size, np.inf)
    for table, blend_s in timed:
        at = np.searchsorted(junctions, table.junction)
        best[at] = np.minimum(best[at], blend_s)
    chosen, taken = [], np.zeros(junctions.size, dtype=bool)
    for table, blend_s in timed:
        at = np.searchsorted(junctions, table.junction)
        keep = (blend_s == best[at]) & ~taken[at]
        taken[at[keep]] = True
        chosen.append(table.subset(keep))
    out = chosen[0]
    for table in chosen[1:]:
        out = out.merged(table)
    return out


def _blend_axes_min(table: BlendTable, limit: FloatArray) -> FloatArray:
    """Per blend the smallest of ``limit`` (per axis) over its plane's axes; over all axes for several pieces."""
    values = np.asarray(limit, dtype=float)
    return np.where(table.has_pieces, values.min(), values[table.plane].min(axis=1))


def _blend_length_m(table: BlendTable) -> FloatArray:
    """Each blend's length, m: its arc's, or the sum of its pieces'."""
    length = table.radius_m * _arc_sweep_rad(table)
    for i in np.flatnonzero(table.has_pieces).tolist():
        length[i] = sum(piece.length_m for piece in table.pieces[i])
    return length


def _arc_sweep_rad(table: BlendTable) -> FloatArray:
    """Each blend arc's sweep, rad (the angle between its ends seen from its centre; < π for a corner's fillet)."""
    a, b = table.start_m - table.center_m, table.end_m - table.center_m
    cross = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
    cos = np.clip(np.einsum("ij,ij->i", a, b) / np.maximum(cross, 1e-300), -1.0, 1.0)
    return np.arccos(cos)
