"""A cutting process on any plant: the feed axis's velocity in, the process force out (ROS-free).

The ``plant.cutting`` section (:class:`CuttingConfig`) puts a process from
:data:`CUTTING_PROCESSES` behind one axis of any plant of
:data:`cnc_plant_sim.models.plant.PLANTS`, as ``plant.faults`` puts machine faults
behind it: the drive model stays the registry's, the cut is orthogonal to it.
Per plant step of ``dt_s`` (:class:`CuttingPlant`)::

    v0 = v_feed(t)                  the feed axis's velocity before the step [m/s]
    inner.step(commands, dt_s)      the drive model integrates
    v1 = v_feed(t + dt_s)           and after it
    F  = process.step(|(v0 + v1)/2|, dt_s)  the process under the mean feed velocity (trapezoid rule)

The feed is one axis for ``turning`` (``feed_axis``), the vector of
``milling.feed_axes`` for ``milling`` (``cnc_plant_sim.process.milling``); its magnitude is fed.

The force is what a dynamometer measures (with its lag and noise, if
configured), published as ``cutting_force`` every tick. Convention: a
``WrenchStamped`` in frame ``tool`` whose ``force.x`` is the main cutting force
F_c [N] (along the cutting speed, what paper 004 regulates); the other
components are 0 (the model has no feed or thrust force). The process does not
load the axes: ``forces_n()`` stays the drive model's.

Depth-of-cut schedules are two flat lists (``depth_schedule_t_s``,
``depth_schedule_mm``): ROS parameters cannot hold a list of pairs. A scenario
may give ``depth_schedule: [[t_s, depth_mm], ...]`` instead
(:meth:`CuttingConfig.from_mapping` splits it).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.force_model import DepthSchedule
from cnc_contour_control.core.params import config_values, param
from cnc_plant_sim.process.milling import MillingConfig, MillingProcess
from cnc_plant_sim.process.turning import PAPER004_DEPTHS, TurningConfig, TurningProcess

__all__ = ["CUTTING_PROCESSES", "CuttingConfig", "CuttingPlant", "CuttingProcessEntry", "cutting_force_n",
           "cutting_plant"]

#: Frame of the ``cutting_force`` wrench (its ``force.x`` is F_c).
TOOL_FRAME = "tool"
#: The ``process`` value of a plant that does not cut.
NO_PROCESS = "none"



@dataclass(frozen=True)
class CuttingProcessEntry:
    """One process: the validated section -> a fresh process (``step(feed_speed_m_s, dt_s) -> N``), the
    plant axes whose velocity vector is its feed (the magnitude of their mean over the step is fed), and the
    option naming them (for errors)."""

    build: Callable[[CuttingConfig], TurningProcess | MillingProcess]
    feed_axes: Callable[[CuttingConfig], tuple[str, ...]]
    feed_option: str


#: Cutting processes by name.
CUTTING_PROCESSES: dict[str, CuttingProcessEntry] = {
    "turning": CuttingProcessEntry(lambda config: TurningProcess(config.turning), lambda config: (config.feed_axis,),
                                   "feed_axis"),
    "milling": CuttingProcessEntry(lambda config: MillingProcess(config.milling, config.depth_schedule()),
                                   lambda config: config.milling.feed_axes, "milling.feed_axes"),
}


@dataclass(frozen=True)
class CuttingConfig:
    """The ``plant.cutting`` section: which process, behind which axis, on which depth schedule.

    Parameters
    ----------
    process : str
        ``none`` (no cut) or a name in :data:`CUTTING_PROCESSES`.
    feed_axis : str
        The plant axis whose velocity is the feed (its magnitude counts).
    depth_schedule_t_s : tuple of float
        Times [s] of the depth-of-cut schedule, strictly increasing.
    depth_schedule_mm : tuple of float
        Depth of cut [mm] from each time on (>= 0), as many as the times.
    turning : TurningConfig or Mapping
        The turning process (paper 004, Eqs. 2-4); its ``depth_schedule`` is the two lists above.
    milling : MillingConfig or Mapping
        The milling process (:mod:`cnc_plant_sim.process.milling`); the two lists above are its axial depth a_p,
        its ``feed_axes`` the feed, its resultant force in the feed plane the ``force.x`` published.
    """

    process: str = param(NO_PROCESS, read_only=True, description="cutting process (none, turning, milling)")
    feed_axis: str = param("x", read_only=True, description="axis whose velocity is the feed (turning)")
    depth_schedule_t_s: tuple[float, ...] = param(tuple(t for t, _ in PAPER004_DEPTHS), unit="s", read_only=True,
                                                  description="times of the depth-of-cut schedule, increasing")
    depth_schedule_mm: tuple[float, ...] = param(tuple(d for _, d in PAPER004_DEPTHS), unit="mm", read_only=True,
                                                 description="depth of cut from each schedule time on")
    turning: TurningConfig = param(default_factory=TurningConfig, read_only=True,
                                   description="the turning process (K_s, spindle, noise, dynamometer)")
    milling: MillingConfig = param(default_factory=MillingConfig, read_only=True,
                                   description="the milling process (coefficients, tool, spindle, feed axes)")

    def __post_init__(self) -> None:
        require_choice("cutting.process", self.process, (NO_PROCESS, *CUTTING_PROCESSES))
        if not isinstance(self.feed_axis, str) or not self.feed_axis:
            raise ConfigError(f"cutting.feed_axis must be an axis name, got {self.feed_axis!r}")
        times, depths = (_numbers(name, getattr(self, name)) for name in ("depth_schedule_t_s", "depth_schedule_mm"))
        if len(times) != len(depths):
            raise ConfigError(f"cutting.depth_schedule_mm must have one depth per time ({len(times)}), "
                              f"got {len(depths)}")
        turning: object = self.turning  # a mapping from a file until built below
        if isinstance(turning, Mapping):
            turning = dict(turning)
            derived = turning.pop("depth_schedule", None)  # config_values gives it back: the same is fine
            if derived is not None and [list(map(float, row)) for row in derived] != [
                    [t, d] for t, d in zip(times, depths)]:
                raise ConfigError("cutting.turning.depth_schedule: give cutting.depth_schedule "
                                  "(or depth_schedule_t_s and depth_schedule_mm)")
            turning = build_config(TurningConfig, turning, context="cutting.turning")
        elif not isinstance(turning, TurningConfig):
            raise ConfigError(f"cutting.turning must be a mapping, got {turning!r}")
        try:
            turning = dataclasses.replace(turning, depth_schedule=tuple(zip(times, depths)))
        except ConfigError as err:
            raise ConfigError(f"cutting.{err}") from err
        object.__setattr__(self, "depth_schedule_t_s", times)
        object.__setattr__(self, "depth_schedule_mm", depths)
        object.__setattr__(self, "turning", turning)
        if isinstance(self.milling, Mapping):
            object.__setattr__(self, "milling", build_config(MillingConfig, self.milling, context="cutting.milling"))
        elif not isinstance(self.milling, MillingConfig):
            raise ConfigError(f"cutting.milling must be a mapping, got {self.milling!r}")

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any] | None, context: str = "cutting") -> CuttingConfig:
        """Build from a mapping (``depth_schedule: [[t_s, depth_mm], ...]`` split into the two lists)."""
        if mapping is not None and not isinstance(mapping, Mapping):
            raise ConfigError(f"{context} must be a mapping, got {mapping!r}")
        values = dict(mapping or {})
        if "depth_schedule" in values:
            flat = sorted({"depth_schedule_t_s", "depth_schedule_mm"} & set(values))
            if flat:
                raise ConfigError(f"{context}.depth_schedule and {context}.{flat[0]} both give the schedule: "
                                  "give one of them")
            values.update(_split_schedule(values.pop("depth_schedule"), context))
        return build_config(cls, values, context=context)

    @property
    def active(self) -> bool:
        """True when the plant cuts (it then publishes ``cutting_force``)."""
        return self.process != NO_PROCESS

    def depth_schedule(self) -> DepthSchedule:
        """The depth of cut against time (milling: the axial depth a_p)."""
        return DepthSchedule(tuple(zip(self.depth_schedule_t_s, self.depth_schedule_mm)))

    def values(self) -> dict[str, Any]:
        """Plain values as the plant node declares them (the derived ``turning.depth_schedule`` left out)."""
        values = config_values(self)
        del values["turning"]["depth_schedule"]
        return values


def _numbers(name: str, value: Any) -> tuple[float, ...]:
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or not value:
        raise ConfigError(f"cutting.{name} must be a non-empty list of numbers, got {value!r}")
    if any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise ConfigError(f"cutting.{name} must hold numbers, got {list(value)!r}")
    return tuple(float(v) for v in value)


def _split_schedule(schedule: Any, context: str) -> dict[str, list[Any]]:
    """``[[t_s, depth_mm], ...]`` -> the two lists (each row checked for its shape)."""
    if isinstance(schedule, (str, bytes)) or not isinstance(schedule, Sequence) or not all(
            isinstance(row, Sequence) and not isinstance(row, str) and len(row) == 2 for row in schedule):
        raise ConfigError(f"{context}.depth_schedule must be a list of [t_s, depth_mm] pairs, got {schedule!r}")
    return {"depth_schedule_t_s": [row[0] for row in schedule], "depth_schedule_mm": [row[1] for row in schedule]}


class CuttingPlant:
    """Any plant with a cutting process behind its feed axis; all but ``step``/``reset`` are the inner plant's.

    Parameters
    ----------
    inner : Plant
        The drive model (or a plant with machine faults).
    cutting : CuttingConfig
        An active section whose ``feed_axis`` is one of the plant's axes.
    """

    def __init__(self, inner: Any, cutting: CuttingConfig) -> None:
        entry = CUTTING_PROCESSES[cutting.process]
        feed_axes = entry.feed_axes(cutting)
        for axis in feed_axes:
            if axis not in inner.axis_names:
                raise ConfigError(f"cutting.{entry.feed_option} must be one of the plant's axes "
                                  f"{list(inner.axis_names)}, got {axis!r}")
        self.inner, self.cutting = inner, cutting
        self.process = entry.build(cutting)
        self.axis_names: tuple[str, ...] = tuple(inner.axis_names)
        self.command_unit: str = inner.command_unit
        self._feed = [self.axis_names.index(axis) for axis in feed_axes]
        self.positions_m, self.velocities_m_s, self.state = inner.positions_m, inner.velocities_m_s, inner.state
        self.forces_n = inner.forces_n

    def reset(self, positions_m: Sequence[float] | None = None) -> None:
        """The inner plant at rest at ``positions_m``; the process at time 0, no force."""
        self.inner.reset(positions_m)
        self.process.reset()

    def step(self, commands: Sequence[float], dt_s: float) -> None:
        """The inner plant's step, then the process under the step's mean feed velocity (module docstring)."""
        before_m_s = [self.inner.state()[1][i] for i in self._feed]
        self.inner.step(commands, dt_s)
        after_m_s = self.inner.state()[1]
        self.process.step(math.hypot(*(0.5 * (v0 + after_m_s[i]) for v0, i in zip(before_m_s, self._feed))), dt_s)

    def cutting_force_n(self) -> float:
        """The measured main cutting force F_c [N] now."""
        return self.process.measured_n

    def describe(self) -> dict[str, Any]:
        """The inner plant as drawn, with the process."""
        return {**self.inner.describe(), "cutting": {"feed_axis": self.cutting.feed_axis, **self.process.describe()}}


def cutting_plant(plant: Any) -> CuttingPlant | None:
    """The :class:`CuttingPlant` inside ``plant`` (itself or an ``inner`` of a wrapper), else None."""
    while plant is not None:
        if isinstance(plant, CuttingPlant):
            return plant
        plant = getattr(plant, "inner", None)
    return None


def cutting_force_n(plant: Any) -> float | None:
    """The measured cutting force [N] of ``plant``, None when it does not cut."""
    cutting = cutting_plant(plant)
    return None if cutting is None else cutting.cutting_force_n()
