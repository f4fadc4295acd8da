"""The time-optimal traversal of a program under per-axis limits, computed independently with ``toppra``.

``toppra`` (TOPP-RA, reachability analysis) solves for the path speed
``ṡ(s)`` on a grid with the per-axis constraints ``|ṡ T_j| <= vmax_j`` and
``|s̈ T_j + ṡ² K_j| <= amax_j`` (``T``, ``K``: unit tangent and curvature
vector of the program, evaluated exactly from its segments) plus the
programmed feed ``ṡ <= F(s)``, written as the velocity limit of one extra
coordinate equal to ``s``. The grid holds every segment boundary, a point
1 nm before it (so both sides' curvature constrain the junction) and points at
most ``spacing_m`` apart. Junctions with a tangent jump are stops (the
program is cut there: :func:`corner_pieces`). It is a bench dependency, not a
run-time one.
"""
from __future__ import annotations

import numpy as np
import toppra
import toppra.algorithm
import toppra.constraint
from toppra.interpolator import AbstractGeometricPath

from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import Program

_BEFORE_M = 1.0e-9
_FREE_ACCELERATION_M_S2 = 1.0e9


class ProgramPath(AbstractGeometricPath):  # type: ignore[misc]  # toppra ships no types (Any base)
    """``toppra``'s view of ``program`` by arc length: the axes plus one coordinate equal to ``s`` (the feed)."""

    def __init__(self, program: Program) -> None:
        self.program = program
        self._ends = program.segment_start_m + np.array([seg.length_m for seg in program.segments])

    @property
    def dof(self) -> int:
        """Axes plus the feed coordinate."""
        return self.program.n_axes + 1

    @property
    def path_interval(self) -> np.ndarray:
        """Start and end arc length, m."""
        return np.array([0.0, self.program.total_length_m])

    def segment_of(self, s_m: np.ndarray) -> np.ndarray:
        """Segment index at each arc length (a boundary belongs to the segment after it)."""
        index = np.searchsorted(self.program.segment_start_m, s_m, side="right") - 1
        return np.clip(index, 0, len(self.program.segments) - 1)

    def __call__(self, path_positions: np.ndarray | float, order: int = 0) -> np.ndarray:
        """Position (order 0), unit tangent (1) or curvature vector (2) at ``path_positions``, plus the feed's."""
        s = np.atleast_1d(np.asarray(path_positions, dtype=float))
        out = np.zeros((s.size, self.dof))
        index = self.segment_of(s)
        for k in np.unique(index):
            rows = np.flatnonzero(index == k)
            segment = self.program.segments[int(k)]
            local = s[rows] - self.program.segment_start_m[k]
            evaluate = (segment.point, segment.tangent, segment.curvature_vector)[order]
            out[rows, :-1] = evaluate(local)
        out[:, -1] = (s, np.ones_like(s), np.zeros_like(s))[order]
        return out if np.ndim(path_positions) else out[0]

    def feed_limits(self, s_m: float) -> np.ndarray:
        """toppra's varying velocity limits at ``s_m``: shape ``(dof, 2)``, the feed coordinate's the segment's feed."""
        feed = self.program.segments[int(self.segment_of(np.array([s_m]))[0])].feed_m_s
        return np.array([[-feed, feed]] * self.dof)


def grid_m(program: Program, spacing_m: float) -> np.ndarray:
    """Grid points, m: segment boundaries, 1 nm before each inner one, and at most ``spacing_m`` apart."""
    points = [np.array([program.total_length_m])]
    for start, segment in zip(program.segment_start_m, program.segments):
        count = max(int(np.ceil(segment.length_m / spacing_m)), 1)
        points.append(start + np.linspace(0.0, segment.length_m, count, endpoint=False))
        if start > 0.0 and segment.length_m > 4 * _BEFORE_M:
            points.append(np.array([start - _BEFORE_M]))
    return np.unique(np.concatenate(points))


def corner_pieces(program: Program, tolerance_rad: float = 1.0e-4 * np.pi / 180.0) -> list[Program]:
    """``program`` cut at every junction whose tangents differ by more than ``tolerance_rad`` (and at dwells).

    A tangent jump needs a stop (unbounded curvature); toppra, which sees the
    path only at grid points, would not notice it, so each piece runs from rest to rest.
    """
    pieces, first = [], 0
    segments = program.segments
    for k in range(1, len(segments) + 1):
        if k < len(segments):
            cosine = float(np.dot(segments[k - 1].tangent(segments[k - 1].length_m), segments[k].tangent(0.0)))
            if np.arccos(min(1.0, max(-1.0, cosine))) <= tolerance_rad and not program.junction_dwell_s[k]:
                continue
        pieces.append(Program(f"{program.name}[{first}:{k}]", program.axis_names, segments[first:k]))
        first = k
    return pieces


def time_optimal_s(program: Program, limits: AxisLimits, spacing_m: float) -> float:
    """Time-optimal duration (s) of ``program`` under ``limits`` and its feeds, stopping at its corners and dwells."""
    return sum(_piece_time_s(piece, limits, spacing_m) for piece in corner_pieces(program)) \
        + float(np.sum(program.junction_dwell_s))


def _piece_time_s(program: Program, limits: AxisLimits, spacing_m: float) -> float:
    """Time-optimal duration (s) of a tangent-continuous ``program`` from rest to rest."""
    path = ProgramPath(program)
    velocity = np.asarray(limits.max_velocity_m_s)
    acceleration = np.append(np.asarray(limits.max_acceleration_m_s2), _FREE_ACCELERATION_M_S2)
    axis_velocity = np.append(velocity, np.inf)

    def velocity_limits(s_m: float) -> np.ndarray:
        bounds = path.feed_limits(s_m)
        bounds[:-1, 1] = np.minimum(bounds[:-1, 1], axis_velocity[:-1])
        bounds[:-1, 0] = -bounds[:-1, 1]
        return bounds

    constraints = [toppra.constraint.JointVelocityConstraintVarying(velocity_limits),
                   toppra.constraint.JointAccelerationConstraint(acceleration)]
    grid = grid_m(program, spacing_m)
    solver = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
    _, speed, _ = solver.compute_parameterization(0.0, 0.0)
    if speed is None:
        raise FaultError(f"toppra found no parameterisation of {program.name!r}")
    speed = np.asarray(speed)  # ṡ at the grid points (toppra 0.6 returns sd_vec = sqrt(x))
    mean = 0.5 * (speed[1:] + speed[:-1])
    return float(np.sum(np.diff(grid) / np.maximum(mean, 1e-300)))

