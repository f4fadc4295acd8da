"""Path, contour and goal tolerances of a goal, and the checks that end it (ROS-free).

A goal (RunProgram, FollowTrajectory) may give, as control_msgs/FollowJointTrajectory does, per axis a
*path* tolerance (|reference - measured| while the reference moves) and a *goal* tolerance (|end - measured|
and |measured velocity| once the reference has ended), a *goal time* (how long after the reference ended
every axis may take to be within its goal tolerance and stopped) and, ours, a *contour* tolerance (the
measured position's distance to the programmed path). Each requested value means::

    > 0    the bound
    0      the node's default (ToleranceDefaults; a default of 0 is "not checked" for path and contour)
    < 0    not checked

:func:`resolve_tolerances` turns a goal's request into one bound per axis (``inf``: not checked);
:class:`ToleranceMonitor` checks a tick and words a violation: the axis (or ``contour``), the amount, the
bound, the time since the goal started and the G-code line (0: not from G-code).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.core.units import mm_to_m
from cnc_contour_control.motion.geometry import FloatArray

#: The outcomes of a violation (their RunProgram result codes follow OUTCOMES' order in program_session).
PATH_VIOLATED = "path_tolerance_violated"
GOAL_VIOLATED = "goal_tolerance_violated"


@dataclass(frozen=True)
class AxisTolerance:
    """One axis's requested tolerance (a JointTolerance message): position m, velocity m/s (see the module)."""

    name: str
    position_m: float = 0.0
    velocity_m_s: float = 0.0


@dataclass(frozen=True)
class GoalTolerances:
    """A goal's requested tolerances (each value > 0 the bound, 0 the default, < 0 not checked)."""

    contour_m: float = 0.0
    path: tuple[AxisTolerance, ...] = field(default=())
    goal: tuple[AxisTolerance, ...] = field(default=())
    goal_time_s: float = 0.0


@dataclass(frozen=True)
class ToleranceDefaults:
    """The node's defaults, SI units; 0 for ``contour_m`` or ``path_m``: not checked."""

    contour_m: float = 0.0
    path_m: float = 0.0
    goal_m: float = 1.0e-5
    goal_velocity_m_s: float = 1.0e-3
    goal_time_s: float = 5.0

    @classmethod
    def from_mm(cls, contour_mm: float, path_mm: float, goal_mm: float, goal_velocity_mm_s: float,
                goal_time_s: float) -> ToleranceDefaults:
        """The defaults from the node's parameters in mm and mm/s."""
        return cls(mm_to_m(contour_mm), mm_to_m(path_mm), mm_to_m(goal_mm), mm_to_m(goal_velocity_mm_s),
                   float(goal_time_s))


@dataclass(frozen=True)
class Tolerances:
    """Resolved bounds: per axis, shape ``(n_axes,)``, ``inf`` where not checked; SI units."""

    contour_m: float
    path_m: FloatArray
    goal_m: FloatArray
    goal_velocity_m_s: FloatArray
    goal_time_s: float


def _bound(requested: float, default: float, what: str) -> float:
    value = float(requested)
    if math.isnan(value) or value == math.inf:
        raise ProgramError(f"{what} must be a finite number (> 0 a bound, 0 the default, < 0 not checked), "
                           f"got {value}")
    if value < 0.0:
        return math.inf
    chosen = value if value > 0.0 else float(default)
    return chosen if chosen > 0.0 else math.inf


def _per_axis(axes: tuple[str, ...], given: Sequence[AxisTolerance], attribute: str, default: float,
              what: str) -> FloatArray:
    bounds = np.full(len(axes), _bound(0.0, default, what))
    seen: set[str] = set()
    for tolerance in given:
        if tolerance.name not in axes:
            raise ProgramError(f"{what}: unknown axis {tolerance.name!r}; the axes are {list(axes)}")
        if tolerance.name in seen:
            raise ProgramError(f"{what}: axis {tolerance.name!r} given twice")
        seen.add(tolerance.name)
        bounds[axes.index(tolerance.name)] = _bound(getattr(tolerance, attribute), default,
                                                    f"{what} of axis {tolerance.name}")
    return bounds


def resolve_tolerances(requested: GoalTolerances, axes: Sequence[str], defaults: ToleranceDefaults) -> Tolerances:
    """One bound per axis from a goal's request and the node's defaults; a ProgramError naming a bad value."""
    names = tuple(axes)
    goal_time_s = float(requested.goal_time_s)
    if not (math.isfinite(goal_time_s) and goal_time_s >= 0.0):
        raise ProgramError(f"goal_time_s must be finite and >= 0 (0: the node's {defaults.goal_time_s:g} s), "
                           f"got {goal_time_s}")
    return Tolerances(
        contour_m=_bound(requested.contour_m, defaults.contour_m, "contour tolerance"),
        path_m=_per_axis(names, requested.path, "position_m", defaults.path_m, "path tolerance"),
        goal_m=_per_axis(names, requested.goal, "position_m", defaults.goal_m, "goal tolerance"),
        goal_velocity_m_s=_per_axis(names, requested.goal, "velocity_m_s", defaults.goal_velocity_m_s,
                                    "goal velocity tolerance"),
        goal_time_s=goal_time_s if goal_time_s > 0.0 else defaults.goal_time_s)


def _where(time_s: float, line: int) -> str:
    return f"at {time_s:.3f} s" + (f", G-code line {line}" if line else " (no G-code line)")


class ToleranceMonitor:
    """Checks ticks against resolved :class:`Tolerances` for the axes ``axes``; each check returns a violation's
    reason or ``None``."""

    def __init__(self, axes: Sequence[str], tolerances: Tolerances) -> None:
        self.axes, self.tolerances = tuple(axes), tolerances

    def path(self, time_s: float, reference_m: FloatArray, measured_m: FloatArray, line: int) -> str | None:
        """The axis furthest beyond its path tolerance, worded; None if every axis is within."""
        excess = np.abs(np.asarray(reference_m) - np.asarray(measured_m)) - self.tolerances.path_m
        worst = int(np.argmax(excess))
        if not excess[worst] > 0.0:
            return None
        off_m = excess[worst] + self.tolerances.path_m[worst]
        return (f"path tolerance violated: axis {self.axes[worst]} {1e3 * off_m:.4f} mm from its reference "
                f"(tolerance {1e3 * self.tolerances.path_m[worst]:g} mm) {_where(time_s, line)}")

    def contour(self, time_s: float, distance_m: float, line: int) -> str | None:
        """The contour error beyond the contour tolerance, worded; None if within."""
        if not distance_m > self.tolerances.contour_m:
            return None
        return (f"path tolerance violated: contour {1e3 * distance_m:.4f} mm from the programmed path "
                f"(tolerance {1e3 * self.tolerances.contour_m:g} mm) {_where(time_s, line)}")

    def in_goal(self, end_m: FloatArray, measured_m: FloatArray, velocity_m_s: FloatArray) -> bool:
        """Every axis within its goal tolerance of ``end_m`` and slower than its goal velocity tolerance."""
        off_m = np.abs(np.asarray(end_m) - np.asarray(measured_m))
        return bool(np.all(off_m <= self.tolerances.goal_m)
                    and np.all(np.abs(velocity_m_s) <= self.tolerances.goal_velocity_m_s))

    def goal(self, time_s: float, waited_s: float, end_m: FloatArray, measured_m: FloatArray,
             velocity_m_s: FloatArray, line: int) -> str:
        """Why the axes are not in their goal tolerance ``waited_s`` after the reference ended: the worst axis."""
        tol = self.tolerances
        off_m = np.abs(np.asarray(end_m) - np.asarray(measured_m))
        speed = np.abs(np.asarray(velocity_m_s))
        ratio = np.maximum(off_m / tol.goal_m, speed / tol.goal_velocity_m_s)
        worst = int(np.argmax(ratio))
        axis = self.axes[worst]
        if off_m[worst] > tol.goal_m[worst]:
            what = (f"axis {axis} {1e3 * off_m[worst]:.4f} mm from its end (tolerance "
                    f"{1e3 * tol.goal_m[worst]:g} mm)")
        else:
            what = (f"axis {axis} moving at {1e3 * speed[worst]:.4f} mm/s (tolerance "
                    f"{1e3 * tol.goal_velocity_m_s[worst]:g} mm/s)")
        return (f"goal tolerance violated: {what} {waited_s:.3f} s after the reference ended (goal_time_s "
                f"{tol.goal_time_s:g}) {_where(time_s, line)}")
