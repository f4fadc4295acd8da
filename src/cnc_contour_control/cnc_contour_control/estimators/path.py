"""Contour error from the programmed geometry: the nearest point on the tracked program segment.

The scorer's geometry (``segment.nearest``, as ``Program.contour_distance``
uses it) with the sign of :mod:`.base`::

    q, s = nearest point of segment i to P (exact for lines and planar arcs)
    t    = unit tangent of the segment at s (direction of travel)
    ε_c  = ±‖P − q‖, + when (P − q) has a component >= 0 along the left normal of t in the plane

Per sample the segment index ``i`` moves forward (then, if it did not,
backward) while the neighbouring segment is nearer; a neighbour whose bounding
box is already farther than the current distance is not evaluated (the
scorer's own skip). So a sample costs one or two ``nearest`` calls whatever
the program's length. On a closed program (its end on its start, within
``POSITION_TOLERANCE_M``) the last segment's forward neighbour is the first
and the first's backward neighbour the last, so a tool past the closing
point is measured against the contour it runs on, not the program's end.
Ties keep the current segment (the scorer keeps the first).
:func:`signed_contour_error` is the same signed distance against the whole
program (the exact reference of the fidelity bench).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.estimators.base import ContourEstimate, check_plane, check_sample
from cnc_contour_control.motion.geometry import POSITION_TOLERANCE_M, FloatArray, IntArray, Program, Segment, as_points


@dataclass(frozen=True)
class PathEstimatorConfig:
    """Validated configuration of the path estimator.

    Parameters
    ----------
    max_steps : int
        Most segment moves per sample, in [1, 1e6].
    plane : tuple of int
        Axis indices of the contour plane that fixes the sign and the angle, ``(0, 1)`` = XY.
    """

    max_steps: int = param(64, unit="segments", low=1, high=1_000_000,
                           description="most segments the tracked index moves per sample")
    plane: tuple[int, int] = param((0, 1), read_only=True,
                                   description="axis indices of the contour plane (sign and angle)")

    def __post_init__(self) -> None:
        if isinstance(self.max_steps, bool) or not isinstance(self.max_steps, int):
            raise ConfigError(f"path.max_steps must be an integer, got {self.max_steps!r}")
        check_ranges(self, "path")
        object.__setattr__(self, "plane", check_plane(self.plane, context="path"))


def signed_segment_error(segment: Segment, points: ArrayLike,
                         plane: tuple[int, int] = (0, 1)) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Signed distance from each point to ``segment`` (sign convention of :mod:`.base`).

    Parameters
    ----------
    segment : LineSegment or ArcSegment
        The segment.
    points : array_like, shape (N, n_axes)
        Positions, m.
    plane : tuple of int
        Axis indices of the contour plane.

    Returns
    -------
    error_m : ndarray, shape (N,)
        ``±distance`` to the segment, m (the magnitude is ``segment.nearest``'s).
    s_m : ndarray, shape (N,)
        Arc length of the nearest point on the segment, m.
    nearest_m : ndarray, shape (N, n_axes)
        The nearest point, m.
    angle_rad : ndarray, shape (N,)
        Direction of travel there, projected on ``plane`` (atan2), rad.
    """
    p = as_points(points, segment.n_axes)
    distance, s_m = segment.nearest(p)
    nearest, tangent = segment.point(s_m), segment.tangent(s_m)
    offset = p - nearest
    a, b = plane
    error = np.copysign(distance, left_side(offset[:, a], offset[:, b], tangent[:, a], tangent[:, b]))
    return error, s_m, nearest, np.arctan2(tangent[:, b], tangent[:, a])


def left_side(offset_a: Any, offset_b: Any, tangent_a: Any, tangent_b: Any) -> Any:
    """Offset's component along the left normal of the tangent, unscaled; ``+0.0`` for zero (never ``-0.0``).

    Floats or arrays; only its sign is used: ``copysign(distance, left_side(...))``
    makes the distance positive left of travel and on the line.
    """
    return tangent_a * offset_b - tangent_b * offset_a + 0.0


def signed_contour_error(program: Program, points: ArrayLike,
                         plane: tuple[int, int] = (0, 1)) -> tuple[FloatArray, IntArray, FloatArray]:
    """The exact signed contour error of each point against the whole program.

    The magnitude and the segment are ``program.contour_distance``'s (the
    scorer's); the sign is :func:`signed_segment_error`'s on that segment.

    Returns
    -------
    error_m : ndarray, shape (N,)
        Signed distance to the contour, m.
    segment_index : ndarray of int, shape (N,)
        Segment holding the nearest point.
    path_length_m : ndarray, shape (N,)
        Arc length along the program of the nearest point, m.
    """
    p = as_points(points, program.n_axes)
    distance, index = program.contour_distance(p)
    error, path_length = distance.copy(), np.zeros(distance.size)
    for i in np.unique(index):
        rows = np.flatnonzero(index == i)
        signed, s_m, _, _ = signed_segment_error(program.segments[i], p[rows], plane)
        error[rows] = np.copysign(distance[rows], signed)
        path_length[rows] = program.segment_start_m[i] + s_m
    return error, index, path_length


def check_program(program: Program) -> Program:
    """``program`` if it has segments and is longer than a point; ConfigError saying which otherwise."""
    segments = getattr(program, "segments", None)
    if not segments:
        raise ConfigError("path estimator: the program is empty (no segments); it needs a contour to measure against")
    length = float(getattr(program, "total_length_m", 0.0))
    if length < POSITION_TOLERANCE_M:
        raise ConfigError(f"path estimator: the program is a single point (total length {length:.3g} m < "
                          f"{POSITION_TOLERANCE_M} m); it needs a contour to measure against")
    return program


class PathEstimator:
    """Signed distance to the nearest point of the tracked program segment (see the module docstring).

    Parameters
    ----------
    config : PathEstimatorConfig
        Validated configuration.
    program : Program
        The programmed contour; empty or a single point is a ConfigError.
    """

    def __init__(self, config: PathEstimatorConfig, program: Program) -> None:
        self.config = config
        self.program = check_program(program)
        self._plane = check_plane(config.plane, program.n_axes, "path")
        self._boxes = [tuple(map(tuple, segment.bounding_box_m())) for segment in program.segments]
        self._closed = float(np.linalg.norm(program.end_m - program.start_m)) <= POSITION_TOLERANCE_M
        self._index = 0

    def reset(self) -> None:
        """Track from the first segment again (a new run)."""
        self._index = 0

    @property
    def segment_index(self) -> int:
        """The segment tracked now."""
        return self._index

    def step(self, ref_position_m: Sequence[float], position_m: Sequence[float]) -> ContourEstimate:
        """Estimate the contour error of ``position_m`` (m, axis order); the reference gives the tracking error."""
        program = self.program
        ref, pos = check_sample(ref_position_m, position_m, program.n_axes, program.axis_names)
        point = np.array([pos])
        i, found = self._index, self._evaluate(self._index, point)
        evaluated, steps = 1, 0
        for direction in (1, -1):
            while steps < self.config.max_steps and (step := self._neighbour(i, direction)) is not None:
                if self._box_gap(step, pos) >= abs(found[0]):
                    break
                candidate = self._evaluate(step, point)
                evaluated += 1
                if abs(candidate[0]) >= abs(found[0]):
                    break
                i, found, steps = step, candidate, steps + 1
            if steps:
                break
        self._index = i
        error, nearest, angle = found
        return ContourEstimate(error, tuple(r - p for r, p in zip(ref, pos)), angle, i, nearest,
                               tuple(program.segments[i].start_m.tolist()), evaluated, steps)

    def _neighbour(self, index: int, direction: int) -> int | None:
        """The segment after (``direction`` 1) or before (−1) ``index``; around the end of a closed program."""
        step, count = index + direction, len(self.program.segments)
        if 0 <= step < count:
            return step
        return step % count if self._closed and count > 1 else None

    def _evaluate(self, index: int, point: FloatArray) -> tuple[float, tuple[float, ...], float]:
        """Signed distance to segment ``index`` (m), its nearest point (m) and the travel angle there (rad).

        :func:`signed_segment_error` for one point, with the segment's scalar
        ``frame`` in place of the array ``point``/``tangent`` (the same sign
        rule, :func:`left_side`; ``test_estimators`` checks both agree).
        """
        segment = self.program.segments[index]
        distance, s_m = segment.nearest(point)
        nearest, tangent, _ = segment.frame(float(s_m[0]))
        a, b = self._plane
        side = left_side(point[0, a] - nearest[a], point[0, b] - nearest[b], tangent[a], tangent[b])
        return math.copysign(float(distance[0]), side), tuple(nearest.tolist()), math.atan2(tangent[b], tangent[a])

    def _box_gap(self, index: int, pos: tuple[float, ...]) -> float:
        """Distance from ``pos`` to the bounding box of segment ``index`` (a lower bound of its distance), m."""
        low, high = self._boxes[index]
        return math.sqrt(sum(max(lo - p, p - hi, 0.0) ** 2 for p, lo, hi in zip(pos, low, high)))
