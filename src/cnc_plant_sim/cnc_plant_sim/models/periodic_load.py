"""A periodic cutting load at the input of any plant: paper 002's A sin(2π f_d t + θ) on papers 000/001 (ROS-free).

The ``plant.periodic_load`` section (:class:`PeriodicLoadConfig`) wraps any
plant of :data:`cnc_plant_sim.models.plant.PLANTS` in a :class:`PeriodicLoadPlant`,
as ``plant.cutting`` and ``plant.faults`` wrap it: the drive model stays the
registry's. Per plant step of ``dt_s`` and axis i::

    d_i = amplitude · sin(φ(t) + θ_i)       held over the step (evaluated at its start)
    inner.step(u − d, dt_s)                  the load acts at the plant input, in the command's unit

``amplitude`` is in the plant's command unit (DAC for ``paper000``, N for
``paper001``), so ``w = u − d`` is paper 002's "T_L at the plant input"
(:mod:`cnc_plant_sim.models.velocity_loop` writes its own disturbance the same way).
φ(t) comes from the one spindle schedule of the suite,
:class:`~cnc_contour_control.axis.spindle.SpindleSchedule` (f_d = rpm · flutes /
60, piecewise constant, φ continuous across a change), the code the
velocity-loop plants use: there is no second periodic-disturbance model.

A spindle override at run time (:func:`set_spindle_rpm`, the plant node's
``spindle_rpm`` parameter) ends the schedule at the plant's present time
and holds the new speed from there on (:func:`schedule_from`), φ continuous;
it reaches every part of a plant that is driven by the spindle (this
wrapper, a velocity-loop plant), through the ``inner`` chain of wrappers.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from cnc_contour_control.axis.spindle import SpindleSchedule
from cnc_contour_control.axis.spindle_follower import spindle_schedule
from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, config_values, param
from cnc_contour_control.disturbance.design import disturbance_frequency_hz

#: Largest load amplitude a config accepts [command unit].
MAX_AMPLITUDE = 1.0e6


@dataclass(frozen=True)
class SpindleFields:
    """The spindle's speed over a run: the fields every plant section with a spindle declares, and their check.

    A base of :class:`PeriodicLoadConfig` and of the velocity-loop plants'
    ``VelocityLoopOptions``: one declaration, one validator, one schedule.

    Parameters
    ----------
    spindle_rpm : float
        Spindle speed from t = 0 [rpm], in [0, 1e6].
    flutes : int
        Cutting edges (flutes) of the tool, in [1, 1000].
    spindle_schedule_t_s : tuple of float
        Times the spindle speed changes [s], > 0, strictly increasing.
    spindle_schedule_rpm : tuple of float
        The speed from each of those times on [rpm], > 0, one per time.
    """

    spindle_rpm: float = param(1500.0, unit="rpm", low=0.0, high=1.0e6, read_only=True,
                               description="spindle speed from t = 0 (f_d = rpm * flutes / 60)")
    flutes: int = param(2, low=1, high=1000, read_only=True, description="cutting edges (flutes) of the tool")
    spindle_schedule_t_s: tuple[float, ...] = param((), unit="s", read_only=True,
                                                    description="times the spindle speed changes, increasing")
    spindle_schedule_rpm: tuple[float, ...] = param((), unit="rpm", read_only=True,
                                                    description="spindle speed from each schedule time on")

    def check_fields(self, context: str) -> None:
        """Check every field (``flutes`` an integer, the ranges, the schedule), errors prefixed ``context.``.

        The schedule's lists are stored as float tuples, ``flutes`` as an int.
        """
        if isinstance(self.flutes, bool) or not isinstance(self.flutes, (int, np.integer)):
            raise ConfigError(f"{context}.flutes must be an integer in [1, 1000], got {self.flutes!r}")
        check_ranges(self, context)
        try:
            times, rpms = spindle_schedule(self.spindle_schedule_t_s, self.spindle_schedule_rpm)
        except ConfigError as err:
            raise ConfigError(f"{context}.{err}") from err
        if times and times[0] <= 0.0:
            raise ConfigError(f"{context}.spindle_schedule_t_s[0] must be > 0, got {times[0]:g}")
        object.__setattr__(self, "flutes", int(self.flutes))
        object.__setattr__(self, "spindle_schedule_t_s", times)
        object.__setattr__(self, "spindle_schedule_rpm", rpms)

    def schedule(self) -> SpindleSchedule:
        """The spindle speed over the run (f_d = rpm · flutes / 60 and its phase)."""
        return SpindleSchedule.from_rpm(self.spindle_rpm, self.flutes, self.spindle_schedule_t_s,
                                        self.spindle_schedule_rpm)


@dataclass(frozen=True)
class PeriodicLoadConfig(SpindleFields):
    """The ``plant.periodic_load`` section: a sinusoidal load at the plant input at the tooth-passing frequency.

    Parameters
    ----------
    spindle_rpm, flutes, spindle_schedule_t_s, spindle_schedule_rpm
        The spindle (:class:`SpindleFields`).
    amplitude : float
        A [command unit: DAC, N, m/s], in [0, 1e6]; 0: no load (the plant is not wrapped).
    phases_rad : tuple of float
        θ per axis in command order [rad], each in [-2π, 2π]; empty: 0 on every axis (a shorter list: 0 after it).
    """

    amplitude: float = param(0.0, unit="command", low=0.0, high=MAX_AMPLITUDE, read_only=True,
                             description="load amplitude A in the plant's command unit (0: no load)")
    phases_rad: tuple[float, ...] = param((), unit="rad", read_only=True,
                                          description="load phase theta per axis (empty: 0)")

    def __post_init__(self) -> None:
        self.check_fields("periodic_load")
        try:
            phases = _phases(self.phases_rad)
        except ConfigError as err:
            raise ConfigError(f"periodic_load.{err}") from err
        object.__setattr__(self, "phases_rad", phases)

    @classmethod
    def from_mapping(cls, mapping: Any, context: str = "periodic_load") -> PeriodicLoadConfig:
        """Build from a mapping; unknown keys are an error listing the valid ones."""
        if not isinstance(mapping, Mapping):
            raise ConfigError(f"{context} must be a mapping, got {mapping!r}")
        return build_config(cls, mapping, context=context)

    @property
    def active(self) -> bool:
        """True when the load is on (amplitude > 0)."""
        return self.amplitude > 0.0

    def phase_rad(self, index: int) -> float:
        """θ of axis ``index`` [rad] (0 beyond the list)."""
        return self.phases_rad[index] if index < len(self.phases_rad) else 0.0


def _phases(values: Any) -> tuple[float, ...]:
    if isinstance(values, (str, bytes)) or not isinstance(values, Sequence):
        raise ConfigError(f"phases_rad must be a list of numbers, got {values!r}")
    for i, value in enumerate(values):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not abs(value) <= 2.0 * math.pi:
            raise ConfigError(f"phases_rad[{i}] must be in [-2pi, 2pi], got {value!r}")
    return tuple(float(v) for v in values)


def schedule_from(schedule: SpindleSchedule, t_s: float, frequency_hz: float) -> SpindleSchedule:
    """``schedule`` up to ``t_s`` [s], then ``frequency_hz`` [Hz] from ``t_s`` on (φ continuous at ``t_s``)."""
    keep = [k for k, start in enumerate(schedule.start_times_s) if start < t_s] or [0]
    starts = [schedule.start_times_s[k] for k in keep]
    frequencies = [schedule.frequencies_hz[k] for k in keep]
    if t_s > starts[-1]:
        starts.append(t_s)
        frequencies.append(frequency_hz)
    else:
        frequencies[-1] = frequency_hz
    return SpindleSchedule(starts, frequencies)


def overridden_schedule(schedule: SpindleSchedule, t_s: float, spindle_rpm: float, flutes: int,
                        sample_time_s: float) -> SpindleSchedule:
    """``schedule`` with ``spindle_rpm`` [rpm] held from ``t_s`` [s] on (a spindle override, φ continuous).

    f_d at or above Nyquist at ``sample_time_s`` is a :class:`ConfigError` (:func:`require_below_nyquist_rpm`).
    """
    rpm = require_below_nyquist_rpm("spindle_rpm", spindle_rpm, int(flutes), sample_time_s)
    return schedule_from(schedule, t_s, disturbance_frequency_hz(rpm, flutes))


def require_below_nyquist_rpm(name: str, spindle_rpm: float, flutes: int, sample_time_s: float) -> float:
    """``spindle_rpm`` if 0 < f_d = rpm · flutes / 60 < 1/(2T); else a :class:`ConfigError` naming the bound."""
    limit_rpm = 30.0 / (sample_time_s * flutes)
    if not (isinstance(spindle_rpm, (int, float)) and 0.0 < spindle_rpm < limit_rpm):
        raise ConfigError(f"{name} must be in (0, {limit_rpm:g}) rpm (f_d = rpm * {flutes} flutes / 60 below "
                          f"Nyquist at T = {sample_time_s:g} s), got {spindle_rpm!r}")
    return float(spindle_rpm)


@runtime_checkable
class SpindleDriven(Protocol):
    """A plant part whose disturbance follows the spindle: it takes a new speed from its present time on."""

    schedule: SpindleSchedule

    def set_spindle_rpm(self, spindle_rpm: float, sample_time_s: float) -> None:
        """Hold ``spindle_rpm`` [rpm] from now on; a :class:`ConfigError` (f_d at or above Nyquist) changes nothing."""


class PeriodicLoadPlant:
    """Any plant with a periodic load at its input; all but ``step``/``reset`` are the inner plant's.

    Parameters
    ----------
    inner : Plant
        The drive model.
    load : PeriodicLoadConfig
        An active section.
    """

    def __init__(self, inner: Any, load: PeriodicLoadConfig) -> None:
        self.inner, self.load = inner, load
        self.axis_names: tuple[str, ...] = tuple(inner.axis_names)
        self.command_unit: str = inner.command_unit
        self.positions_m, self.velocities_m_s, self.state = inner.positions_m, inner.velocities_m_s, inner.state
        self.forces_n = inner.forces_n
        self._phases = [load.phase_rad(i) for i in range(len(self.axis_names))]
        self.schedule = load.schedule()
        self.time_s = 0.0
        self.last_load = [0.0] * len(self.axis_names)

    def reset(self, positions_m: Sequence[float] | None = None) -> None:
        """The inner plant at rest at ``positions_m``; the run's time back to 0, the configured schedule."""
        self.inner.reset(positions_m)
        self.schedule = self.load.schedule()
        self.time_s = 0.0

    def loads(self, t_s: float) -> list[float]:
        """d_i = A sin(φ(t_s) + θ_i) per axis [command unit]."""
        phase, amplitude = self.schedule.phase_rad(t_s), self.load.amplitude
        return [amplitude * math.sin(phase + theta) for theta in self._phases]

    def step(self, commands: Sequence[float], dt_s: float) -> None:
        """The inner plant's step under ``u − d`` (d at the step's start, held); the time advances if it moved."""
        loads = self.loads(self.time_s)
        self.inner.step([float(u) - d for u, d in zip(commands, loads)], dt_s)
        self.last_load = loads
        self.time_s += dt_s

    def set_spindle_rpm(self, spindle_rpm: float, sample_time_s: float) -> None:
        """The load's speed from now on (see :class:`SpindleDriven`)."""
        self.schedule = overridden_schedule(self.schedule, self.time_s, spindle_rpm, self.load.flutes, sample_time_s)

    def describe(self) -> dict[str, Any]:
        """The inner plant as drawn, with the load."""
        return {**self.inner.describe(), "periodic_load": config_values(self.load)}


def periodic_load_plant(plant: Any, load: PeriodicLoadConfig) -> Any:
    """``plant`` with the load at its input when the section is active, else ``plant`` itself."""
    return PeriodicLoadPlant(plant, load) if load.active else plant


def spindle_driven(plant: Any) -> list[SpindleDriven]:
    """Every part of ``plant`` (itself and its ``inner`` chain) whose disturbance follows the spindle."""
    found = []
    while plant is not None:
        if isinstance(plant, SpindleDriven):
            found.append(plant)
        plant = getattr(plant, "inner", None)
    return found


def set_spindle_rpm(plant: Any, spindle_rpm: float, sample_time_s: float) -> int:
    """Give ``spindle_rpm`` [rpm] to every spindle-driven part of ``plant`` from its present time on.

    A refused speed (:class:`ConfigError` naming the parameter, the bound and the value: f_d at or
    above Nyquist at ``sample_time_s``) leaves every part's schedule as it was; a plant without any
    spindle-driven part refuses every speed. Returns the number of parts that took it.
    """
    parts = spindle_driven(plant)
    if not parts:
        raise ConfigError(f"spindle_rpm: the plant has no periodic disturbance to drive (plant.periodic_load."
                          f"amplitude 0 and no velocity-loop model), got {spindle_rpm!r}")
    saved = [part.schedule for part in parts]
    try:
        for part in parts:
            part.set_spindle_rpm(spindle_rpm, sample_time_s)
    except ConfigError:
        for part, schedule in zip(parts, saved):
            part.schedule = schedule
        raise
    return len(parts)
