"""Homing: the move to the home position that makes the axes homed (ROS-free).

As LinuxCNC homes joints in a sequence, the homing program moves one axis at a
time, in axis order, from where the machine stands to its home position at
that axis's homing feed (an axis already there does not move): one line per
axis that moves, an exact stop between them. It runs through the normal
reference, so the servos follow it; once it completes in position every axis
is homed. With ``require_homing`` a program is refused until then, naming the
first axis not homed. Soft travel limits do not apply to the homing move (an
axis may stand outside its travel before it is homed), but the home position
must lie within them.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cnc_contour_control.core.config import require_flag
from cnc_contour_control.core.errors import ConfigError, ProgramError
from cnc_contour_control.core.params import param
from cnc_contour_control.core.units import mm_min_to_m_s
from cnc_contour_control.motion.geometry import LineSegment, Program
from cnc_contour_control.motion.points import MIN_LENGTH_M, FloatArray, require_feed_mm_min
from cnc_contour_control.motion.travel import TravelLimits

#: The homing program's name (in the path and the logs).
HOMING_PROGRAM = "homing"
#: Homing feed of an axis that gives none, mm/min.
DEFAULT_HOMING_FEED_MM_MIN = 1000.0


@dataclass(frozen=True)
class HomingParams:
    """The interpolator's homing options (action mode).

    Parameters
    ----------
    home_position_mm : tuple of float
        Home position of each axis, in axis order, mm (empty: every axis at 0).
    homing_feed_mm_min : tuple of float
        Homing feed of each axis, in axis order, or one for all, mm/min, > 0 (empty: 1000).
    require_homing : bool
        Refuse programs until every axis is homed (LinuxCNC's behaviour).
    """

    home_position_mm: tuple[float, ...] = param((), unit="mm", read_only=True,
                                                description="home position of each axis in axis order "
                                                            "(empty: 0 on every axis)")
    homing_feed_mm_min: tuple[float, ...] = param((), unit="mm/min", read_only=True,
                                                  description="homing feed of each axis in axis order, or one "
                                                              "for all (empty: 1000 mm/min)")
    require_homing: bool = param(False, read_only=True,
                                 description="refuse programs until every axis is homed (call the home service)")

    def __post_init__(self) -> None:
        require_flag("require_homing", self.require_homing)
        try:
            position = tuple(float(v) for v in self.home_position_mm)
        except (TypeError, ValueError) as err:
            raise ConfigError(f"home_position_mm must be a list of numbers (mm), "
                              f"got {self.home_position_mm!r}") from err
        if not np.all(np.isfinite(position)):
            raise ConfigError(f"home_position_mm must be finite, got {list(position)}")
        feed = tuple(require_feed_mm_min("homing_feed_mm_min", v) for v in self.homing_feed_mm_min)
        object.__setattr__(self, "home_position_mm", position)
        object.__setattr__(self, "homing_feed_mm_min", feed)

    def position_m(self, axes: Sequence[str]) -> FloatArray:
        """The home position, m, shape ``(n_axes,)``."""
        if not self.home_position_mm:
            return np.zeros(len(axes))
        if len(self.home_position_mm) != len(axes):
            raise ConfigError(f"home_position_mm needs one value per axis ({list(axes)}), "
                              f"got {list(self.home_position_mm)}")
        return np.array(self.home_position_mm) * 1e-3

    def feed_mm_min(self, axes: Sequence[str]) -> tuple[float, ...]:
        """The homing feed of each axis, mm/min."""
        feeds = self.homing_feed_mm_min or (DEFAULT_HOMING_FEED_MM_MIN,)
        if len(feeds) == 1:
            return feeds * len(axes)
        if len(feeds) != len(axes):
            raise ConfigError(f"homing_feed_mm_min needs 1 or {len(axes)} values ({list(axes)}), got {list(feeds)}")
        return feeds

    def check(self, axes: Sequence[str], travel: TravelLimits) -> None:
        """Refuse (ConfigError) a home position or feed list not matching ``axes``, or a home outside the travel."""
        home_mm = 1e3 * self.position_m(axes)
        self.feed_mm_min(axes)
        for axis, value in zip(axes, home_mm):
            low, high = travel.limit_mm(axis)
            if not low <= value <= high:
                raise ConfigError(f"home_position_mm of axis {axis} must be within its travel [{low:g}, {high:g}] "
                                  f"mm, got {value:g}")


def homing_program(axes: Sequence[str], hold_m: FloatArray, params: HomingParams) -> Program | None:
    """The homing moves from ``hold_m`` (m, ``(n_axes,)``): one line per axis not at home; None if all are."""
    axes = tuple(axes)
    home_m, feeds = params.position_m(axes), params.feed_mm_min(axes)
    point = np.array(hold_m, dtype=float)
    segments = []
    for j in range(len(axes)):
        if abs(home_m[j] - point[j]) < MIN_LENGTH_M:
            continue
        target = point.copy()
        target[j] = home_m[j]
        segments.append(LineSegment(point, target, mm_min_to_m_s(feeds[j])))
        point = target
    return Program(HOMING_PROGRAM, axes, tuple(segments)) if segments else None


class HomedState:
    """Which axes are homed (none at first)."""

    def __init__(self, axes: Sequence[str], required: bool) -> None:
        self.axes, self.required = tuple(axes), bool(required)
        self.homed = [False] * len(self.axes)

    def mark_all(self) -> None:
        """The homing program completed: every axis homed."""
        self.homed = [True] * len(self.axes)

    def check(self) -> None:
        """With ``require_homing``: a ProgramError naming the first axis not homed."""
        if not self.required:
            return
        for axis, homed in zip(self.axes, self.homed):
            if not homed:
                raise ProgramError(f"axis {axis} is not homed; call home first")

    def values(self) -> dict[str, str]:
        """The state as /diagnostics values: ``homed.<axis>`` true/false and ``require_homing``."""
        out = {f"homed.{axis}": str(homed).lower() for axis, homed in zip(self.axes, self.homed)}
        out["require_homing"] = str(self.required).lower()
        return out
