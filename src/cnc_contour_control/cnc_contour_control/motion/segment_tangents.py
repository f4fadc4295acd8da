"""Unit tangents at the ends of many segments at once, and the turn at every junction (for the planner).

The same formulas as :meth:`LineSegment.tangent` and :meth:`ArcSegment.tangent`
(``T_a = -ρ sin θ``, ``T_b = ρ cos θ`` in the arc's plane with
``ρ = dir R sweep / length``, the rise over the length on the other axes),
evaluated over all arcs of one plane in one NumPy call instead of two method
calls per junction.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import cast

import numpy as np

from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.geometry import LineSegment, Segment
from cnc_contour_control.motion.points import FloatArray


def _arc_tangents(arcs: Sequence[ArcSegment], n_axes: int) -> tuple[FloatArray, FloatArray]:
    """Start and end tangents of arcs that share one plane, ``(M, n_axes)`` each."""
    start_angle = np.array([arc.start_angle_rad for arc in arcs])
    direction = np.array([arc.direction for arc in arcs])
    sweep = np.array([arc.sweep_rad for arc in arcs])
    length = np.array([arc.length_m for arc in arcs])
    rate = direction * np.array([arc.radius_m for arc in arcs]) * sweep / length
    rise = np.array([arc.rise_m for arc in arcs]).reshape(len(arcs), n_axes) / length[:, None]
    a, b = arcs[0].plane
    tangents = []
    for theta in (start_angle, start_angle + direction * sweep):
        out = rise.copy()
        out[:, a], out[:, b] = -rate * np.sin(theta), rate * np.cos(theta)
        tangents.append(out)
    return tangents[0], tangents[1]


def end_tangents(segments: Sequence[Segment]) -> tuple[FloatArray, FloatArray]:
    """Unit tangents at the start and at the end of every segment, shape ``(N, n_axes)`` each."""
    n_axes = segments[0].n_axes
    start, end = np.empty((len(segments), n_axes)), np.empty((len(segments), n_axes))
    by_plane: dict[tuple[int, int], list[int]] = {}
    lines = []
    for i, segment in enumerate(segments):
        if isinstance(segment, ArcSegment):
            by_plane.setdefault(segment.plane, []).append(i)
        else:
            lines.append(i)
    if lines:
        start[lines] = end[lines] = np.array([cast(LineSegment, segments[i]).unit_vector for i in lines])
    for rows in by_plane.values():
        start[rows], end[rows] = _arc_tangents([cast(ArcSegment, segments[i]) for i in rows], n_axes)
    return start, end


def junction_turns_rad(segments: Sequence[Segment]) -> FloatArray:
    """Angle between the tangents before and after each inner junction, rad, ``(N - 1,)`` (index k: before k+1)."""
    start, end = end_tangents(segments)
    cosine = np.einsum("ij,ij->i", end[:-1], start[1:])
    return np.arccos(np.clip(cosine, -1.0, 1.0))
