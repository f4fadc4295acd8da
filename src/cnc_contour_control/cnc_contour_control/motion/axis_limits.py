"""Per-axis limits of the planner: velocity, acceleration and, optionally, jerk (m/s, m/s², m/s³)."""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from numpy.typing import ArrayLike

from cnc_contour_control.core.config import require_positive
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import param


@dataclass(frozen=True)
class AxisLimits:
    """Per-axis velocity and acceleration limits, one entry per axis.

    Parameters
    ----------
    max_velocity_m_s : tuple of float
        Largest axis speed, m/s, > 0.
    max_acceleration_m_s2 : tuple of float
        Largest axis acceleration, m/s^2, > 0.
    max_jerk_m_s3 : tuple of float, optional
        Largest axis jerk, m/s^3, > 0, one entry per axis. Given, the planner runs its jerk-limited mode
        (:mod:`cnc_contour_control.motion.jerk_plan`); None (the default): no jerk limit.
    """

    max_velocity_m_s: tuple[float, ...] = param(
        unit="m/s", read_only=True, description="largest speed of each axis, in axis order, each > 0")
    max_acceleration_m_s2: tuple[float, ...] = param(
        unit="m/s^2", read_only=True, description="largest acceleration of each axis, in axis order, each > 0")
    max_jerk_m_s3: tuple[float, ...] | None = param(
        None, unit="m/s^3", read_only=True,
        description="largest jerk of each axis, in axis order, each > 0 (set: the jerk-limited planner)")

    def __post_init__(self) -> None:
        velocity = _positive_tuple("max_velocity_m_s", self.max_velocity_m_s)
        acceleration = _positive_tuple("max_acceleration_m_s2", self.max_acceleration_m_s2)
        if len(velocity) != len(acceleration):
            raise ConfigError(
                f"max_acceleration_m_s2 must have one entry per axis ({len(velocity)}), got {len(acceleration)}")
        object.__setattr__(self, "max_velocity_m_s", velocity)
        object.__setattr__(self, "max_acceleration_m_s2", acceleration)
        if self.max_jerk_m_s3 is not None:
            jerk = _positive_tuple("max_jerk_m_s3", self.max_jerk_m_s3)
            if len(jerk) != len(velocity):
                raise ConfigError(f"max_jerk_m_s3 must have one entry per axis ({len(velocity)}), got {len(jerk)}")
            object.__setattr__(self, "max_jerk_m_s3", jerk)

    @property
    def n_axes(self) -> int:
        """Number of axes."""
        return len(self.max_velocity_m_s)


def _positive_tuple(name: str, values: ArrayLike) -> tuple[float, ...]:
    if isinstance(values, (str, bytes)) or not isinstance(values, Iterable):
        raise ConfigError(f"{name} must be a list with one value per axis, got {values!r}")
    items: list[Any] = list(values)
    if not items:
        raise ConfigError(f"{name} must have at least one entry, got {values!r}")
    return tuple(require_positive(f"{name}[{j}]", v) for j, v in enumerate(items))
