"""Scenarios: one YAML file fixes a run (plant, program, limits, per-axis servo, T, duration, seed).

Every section is validated by the core config it builds, so a bad scenario is
refused before anything starts, with the key, the bound and the value.
"""
from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from cnc_contour_control.axis.servo import ServoConfig
from cnc_contour_control.core.config import (
    build_config,
    read_yaml_mapping,
    require_choice,
    require_positive,
    require_range,
)
from cnc_contour_control.core.errors import CncError, ConfigError
from cnc_contour_control.core.lockstep import seconds_to_ns
from cnc_contour_control.core.params import param_specs
from cnc_contour_control.core.stages import Pipeline, pipeline
from cnc_contour_control.core.units import mm_min_to_m_s, mm_s2_to_m_s2
from cnc_contour_control.force.settings import ForceRegulatorSettings
from cnc_contour_control.graph.cross_axis import CompensatorSettings, EstimatorSettings
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig, planning_limits
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.homing import HomingParams
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.points import require_feed_mm_min
from cnc_contour_control.motion.program import load_program
from cnc_contour_control.motion.travel import TravelLimits
from cnc_plant_sim.models.plant import PlantConfig
from cnc_plant_sim.models.velocity_loop import VelocityLoopOptions
from cnc_plant_sim.run.run_params import PlantRunParams
from cnc_plant_sim.run.watchdog import WatchdogParams
from cnc_tools.runs.scenario_format import check_format

MODES = ("lockstep", "realtime")
#: Scenario sections that switch on an optional stage of the pipeline (the section's name is the stage's).
OPTIONAL_STAGE_KEYS: tuple[str, ...] = ("estimator", "compensator", "force_regulator")
_TOP_KEYS = ("name", "format_version", "description", "sample_time_s", "duration_s", "settle_s", "seed", "mode",
             "plant", "limits", "program", "servo", "interpolator", "paper", "feed_override", "homing", "realtime",
             *OPTIONAL_STAGE_KEYS)
#: The plant's real-time watchdog options a scenario may set (its ``realtime`` section).
_REALTIME_KEYS = tuple(f.name for f in fields(WatchdogParams))
_LIMIT_KEYS = ("max_velocity_mm_min", "max_acceleration_mm_s2", "max_jerk_mm_s3", "travel_mm")
_HOMING_KEYS = ("position_mm", "feed_mm_min", "require_homing")


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. ``raw`` keeps the mapping it was built from (for the run record)."""

    name: str
    description: str
    sample_time_s: float
    duration_s: float
    seed: int
    mode: str
    plant: PlantConfig
    program: Program
    limits: AxisLimits
    interpolator: InterpolatorConfig
    servos: tuple[ServoConfig, ...]
    raw: Mapping[str, Any] = field(repr=False, compare=False)
    source: Path | None = None
    estimator: EstimatorSettings | None = None
    compensator: CompensatorSettings | None = None
    feed_override: OverrideConfig | None = None
    force_regulator: ForceRegulatorSettings | None = None
    #: Soft travel limits (``limits.travel_mm``; none: every axis unbounded).
    travel: TravelLimits = field(default_factory=TravelLimits)
    #: Home position, homing feeds, ``require_homing`` (the ``homing`` section; the interpolator's action mode).
    homing: HomingParams = field(default_factory=HomingParams)
    #: The plant's real-time watchdog options the scenario sets (the ``realtime`` section; the rest: defaults).
    realtime: Mapping[str, Any] = field(default_factory=dict)

    @property
    def axes(self) -> tuple[str, ...]:
        """Axis names, in order."""
        return self.plant.axes

    @property
    def ends_by(self) -> str:
        """``duration`` when the scenario sets its own ``duration_s`` (the run may cut its program), else
        ``program`` (the run lasts the planned program plus ``settle_s``): the verdict's ``ends_by``."""
        return "duration" if self.raw.get("duration_s") is not None else "program"

    @property
    def override_active(self) -> bool:
        """True when the feed can be overridden on line: a ``feed_override`` section or a force regulator."""
        return self.feed_override is not None or self.pipeline().has("force_regulator")

    @property
    def override_config(self) -> OverrideConfig:
        """The on-line override's options (the defaults when only a force regulator asks for it)."""
        return self.feed_override if self.feed_override is not None else OverrideConfig()

    @property
    def override_source(self) -> str:
        """The interpolator's ``feed_override_source``: ``previous_tick`` with a force regulator, ``schedule``
        with a schedule, ``topic`` with a section alone (requests from outside the run), else ``none``."""
        self.check_override_requests()
        if self.pipeline().has("force_regulator"):
            return "previous_tick"
        if self.feed_override is None:
            return "none"
        return "schedule" if self.feed_override.has_schedule else "topic"

    def check_override_requests(self) -> None:
        """Refuses a feed-override schedule beside the force_regulator stage: both would request the override."""
        if self.pipeline().has("force_regulator") and self.override_config.has_schedule:
            raise ConfigError("scenario.feed_override.schedule and the force_regulator stage both request "
                              "the feed override: give one of them")

    def make_interpolator(self) -> Interpolator:
        """A fresh interpolator of this scenario's program (planned for the override's ``max_ratio`` when active)."""
        if self.override_active:
            return Interpolator(self.program, planning_limits(self.limits, self.override_config), self.interpolator)
        return Interpolator(self.program, self.limits, self.interpolator)

    def make_live_reference(self) -> LiveReference:
        """The tick-by-tick reference under the on-line feed override (what the interpolator node steps)."""
        return LiveReference(self.program, self.limits, self.interpolator, self.override_config)

    @property
    def optional_stages(self) -> tuple[str, ...]:
        """The optional pipeline stages this scenario asks for (a section of the stage's name)."""
        return tuple(name for name in OPTIONAL_STAGE_KEYS if self.raw.get(name) is not None)

    def pipeline(self) -> Pipeline:
        """The run's stage pipeline: the core stages plus the optional ones the scenario asks for
        (the plant's ``tool_position`` when it has machine faults, ``cutting_force`` when it cuts)."""
        outputs = {"tool_position": self.plant.faults.active, "cutting_force": self.plant.cutting.active}
        return pipeline(self.axes, self.optional_stages, tuple(name for name, on in outputs.items() if on))

    def variant(self, overrides: Mapping[str, Any] | None = None, **changes: Any) -> Scenario:
        """A validated copy: ``overrides`` deep-merged (as ``--set`` merges), then top-level ``changes`` replacing keys.

        The one way to make scenario variants (sweeps, benches, tuning): the
        copy goes through the same validation as a file, relative program
        files still resolve against the original scenario's folder. A key in
        ``changes`` replaces the whole section (``servo=...`` drops the old
        law's gains, where a merge would keep them beside the new law's).
        """
        raw = {**merge(self.raw, overrides or {}), **changes}
        return build_scenario(raw, base_dir=self.source.parent if self.source else None, source=self.source)


def load_scenario(path: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Read and validate the scenario in ``path`` (with optional top-level overrides)."""
    file = Path(path)
    raw = merge(read_yaml_mapping(file, "scenario file"), overrides or {})
    raw.setdefault("name", file.stem)
    return build_scenario(raw, base_dir=file.parent, source=file)


def merge(base: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """Deep-merge ``overrides`` into a copy of ``base`` (mappings merge, other values replace)."""
    result = copy.deepcopy(dict(base))
    for key, value in overrides.items():
        if isinstance(value, Mapping) and isinstance(result.get(key), Mapping):
            result[key] = merge(result[key], value)
        else:
            result[key] = copy.deepcopy(value)
    return result


def build_scenario(raw: Mapping[str, Any], base_dir: Path | None = None, source: Path | None = None) -> Scenario:
    """Validate a scenario mapping section by section."""
    _refuse_unknown(raw, _TOP_KEYS, "scenario")
    name = str(raw.get("name", "scenario"))
    sample_time_s = require_positive("sample_time_s", raw.get("sample_time_s", 0.01), "scenario")
    mode = require_choice("mode", str(raw.get("mode", "lockstep")), MODES, "scenario")
    _as_the_nodes_take(sample_time_s=sample_time_s, mode=mode)
    seconds_to_ns(sample_time_s)
    seed = _seed(raw)
    plant = PlantConfig.from_mapping({"seed": seed, **_section(raw, "plant", {})}, "scenario.plant")
    program = load_program(_section(raw, "program"), name=name, base_dir=base_dir)
    if tuple(program.axis_names) != plant.axes:
        raise ConfigError(f"scenario.program.axes {list(program.axis_names)} differ from "
                          f"scenario.plant.axes {list(plant.axes)}")
    limits = _limits(raw.get("limits", {}), len(plant.axes))
    travel = _travel(raw.get("limits", {}), plant.axes)
    homing = _homing(raw.get("homing"), plant.axes, travel)
    interpolator = _interpolator_config(_section(raw, "interpolator", {}))
    feed_override = _feed_override(raw.get("feed_override"))
    planned = limits if feed_override is None else planning_limits(limits, feed_override)
    planner = Interpolator(program, planned, interpolator)
    _check_travel(travel, planner)
    duration_s = _duration(raw, planner.duration_s)
    realtime = _realtime(_section(raw, "realtime", {}))
    _as_the_nodes_take(sample_time_s=sample_time_s, duration_s=duration_s, mode=mode)
    scenario = Scenario(
        name=name,
        description=str(raw.get("description", "")),
        sample_time_s=sample_time_s,
        duration_s=duration_s,
        seed=seed,
        mode=mode,
        plant=plant,
        program=program,
        limits=limits,
        interpolator=interpolator,
        servos=_servos(raw.get("servo", {}), plant),
        raw=dict(raw),
        source=source,
        feed_override=feed_override,
        travel=travel,
        homing=homing,
        realtime=realtime,
        **_cross_axis(raw),
    )
    check_format(raw, scenario.servos, sample_time_s)
    scenario.check_override_requests()
    _check_force_loop(scenario)
    return scenario


def _check_force_loop(scenario: Scenario) -> None:
    """A force regulator needs a plant that cuts, and an interpolator that takes its highest override."""
    settings = scenario.force_regulator
    if settings is None:
        return
    if not scenario.plant.cutting.active:
        raise ConfigError("scenario.force_regulator regulates the cutting force: it needs scenario.plant.cutting "
                          "(e.g. cutting: {process: turning, feed_axis: x})")
    highest, allowed = settings.regulator.quantiser.max_ratio, scenario.override_config.max_ratio
    if highest > allowed:
        raise ConfigError(f"scenario.force_regulator.quantiser.max_ratio must be <= feed_override.max_ratio "
                          f"({allowed}), got {highest}")


def _section(raw: Mapping[str, Any], key: str, default: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The mapping under ``key``; ``default`` when absent (or null) if given, else it is required."""
    value = raw.get(key)
    if value is None and default is not None:
        return dict(default)
    if not isinstance(value, Mapping):
        raise ConfigError(f"scenario.{key} must be a mapping, got {value!r}")
    return dict(value)


def _realtime(section: dict[str, Any]) -> dict[str, Any]:
    """The ``realtime`` section: the plant's watchdog options (``max_late_share``, ``max_period_ratio``, ...), each
    checked against the node's range."""
    _refuse_unknown(section, _REALTIME_KEYS, "scenario.realtime")
    try:
        WatchdogParams(**section)
    except (ConfigError, TypeError) as err:
        raise ConfigError(f"scenario.realtime.{err}") from err
    return dict(section)


def _as_the_nodes_take(**values: Any) -> None:
    """Refuse run values the plant node would refuse: its declared parameter ranges are the one bound."""
    try:
        PlantRunParams(**values)
    except ConfigError as err:
        raise ConfigError(f"scenario.{err}") from err


def _seed(raw: Mapping[str, Any]) -> int:
    """The scenario's seed: an integer (the plant checks its range)."""
    value = raw.get("seed", 0)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"scenario.seed must be an integer >= 0, got {value!r}")
    return value


def _refuse_unknown(mapping: Mapping[str, Any], valid: tuple[str, ...], context: str) -> None:
    unknown = sorted(set(mapping) - set(valid))
    if unknown:
        raise ConfigError(f"{context}.{unknown[0]}: unknown key; valid keys are {sorted(valid)}")


#: Longest run the plant takes, s (its declared ``duration_s`` bound): a longer ``settle_s`` is refused by its name.
_MAX_DURATION_S = float(next(s.info.high for s in param_specs(PlantRunParams) if s.name == "duration_s") or 0.0)


def _duration(raw: Mapping[str, Any], planned_s: float) -> float:
    if raw.get("duration_s") is not None:
        return require_positive("duration_s", raw["duration_s"], "scenario")
    return planned_s + require_range("settle_s", raw.get("settle_s", 0.5), 0.0, _MAX_DURATION_S, "scenario")


def _limits(section: Any, n_axes: int) -> AxisLimits:
    if not isinstance(section, Mapping):
        raise ConfigError(f"scenario.limits must be a mapping, got {section!r}")
    _refuse_unknown(section, _LIMIT_KEYS, "scenario.limits")
    velocity = _per_axis(section.get("max_velocity_mm_min", 6000.0), n_axes, "scenario.limits.max_velocity_mm_min")
    accel = _per_axis(section.get("max_acceleration_mm_s2", 1000.0), n_axes, "scenario.limits.max_acceleration_mm_s2")
    return AxisLimits(
        max_velocity_m_s=tuple(mm_min_to_m_s(require_feed_mm_min("max_velocity_mm_min", v, "scenario.limits"))
                               for v in velocity),
        max_acceleration_m_s2=tuple(mm_s2_to_m_s2(_acceleration_mm_s2(a)) for a in accel),
        max_jerk_m_s3=_jerk_m_s3(section.get("max_jerk_mm_s3"), n_axes),
    )


def _jerk_m_s3(value: Any, n_axes: int) -> tuple[float, ...] | None:
    """``limits.max_jerk_mm_s3`` (one value or one per axis, each > 0) in m/s³; absent: no jerk limit."""
    if value is None:
        return None
    return tuple(1.0e-3 * require_positive("max_jerk_mm_s3", j, "scenario.limits")
                 for j in _per_axis(value, n_axes, "scenario.limits.max_jerk_mm_s3"))


def _travel(section: Mapping[str, Any], axes: tuple[str, ...]) -> TravelLimits:
    """``limits.travel_mm: {axis: [min_mm, max_mm], ...}`` (absent: unbounded), axes of the plant only."""
    value = section.get("travel_mm")
    if value is None:
        return TravelLimits()
    if not isinstance(value, Mapping):
        raise ConfigError(f"scenario.limits.travel_mm must be a mapping {{axis: [min_mm, max_mm]}}, got {value!r}")
    try:
        travel = TravelLimits.of(dict(value))
        travel.bounds_m(axes)
    except ConfigError as err:
        raise ConfigError(f"scenario.limits.{err}") from err
    return travel


def _check_travel(travel: TravelLimits, planner: Interpolator) -> None:
    """The planned path (blends included) within the travel limits, else refused naming line, axis and excess."""
    if not travel.active:
        return
    try:
        travel.check_program(planner.program)
    except CncError as err:
        raise ConfigError(f"scenario.limits.travel_mm: {err}") from err


def _homing(section: Any, axes: tuple[str, ...], travel: TravelLimits) -> HomingParams:
    """``homing: {position_mm: {axis: mm}, feed_mm_min: mm/min or {axis: mm/min}, require_homing: bool}``."""
    if section is None:
        return HomingParams()
    if not isinstance(section, Mapping):
        raise ConfigError(f"scenario.homing must be a mapping, got {section!r}")
    _refuse_unknown(section, _HOMING_KEYS, "scenario.homing")
    position = _axis_map(section.get("position_mm", {}), axes, "scenario.homing.position_mm", 0.0)
    feed = section.get("feed_mm_min", ())
    feeds = _axis_map(feed, axes, "scenario.homing.feed_mm_min", None) if isinstance(feed, Mapping) else (
        () if feed == () else (feed,))
    if section.get("require_homing", False) is True:  # as the interpolator refuses it in file mode
        raise ConfigError("scenario.homing.require_homing needs the interpolator's action mode (the home service); "
                          "a scenario's program runs at start-up")
    try:
        homing = HomingParams(tuple(position), tuple(feeds), section.get("require_homing", False))
        homing.check(axes, travel)
    except ConfigError as err:
        raise ConfigError(f"scenario.homing.{err}") from err
    return homing


def _axis_map(value: Any, axes: tuple[str, ...], context: str, absent: float | None) -> list[Any]:
    """``{axis: value}`` in axis order; an absent axis takes ``absent`` (None: every axis is required)."""
    if not isinstance(value, Mapping):
        raise ConfigError(f"{context} must be a mapping {{axis: value}}, got {value!r}")
    _refuse_unknown(value, axes, context)
    if absent is None and set(value) != set(axes):
        raise ConfigError(f"{context} needs every axis {list(axes)}, got {sorted(value)}")
    return [value.get(axis, absent) for axis in axes]


#: Smallest acceleration limit, mm/s² (0.1 mm in 14 s from rest): lower, no program ends within a run.
MIN_ACCELERATION_MM_S2 = 1.0e-3


def _acceleration_mm_s2(value: Any) -> float:
    """An axis's acceleration limit, refused by its name below :data:`MIN_ACCELERATION_MM_S2`."""
    number = require_positive("max_acceleration_mm_s2", value, "scenario.limits")
    if number < MIN_ACCELERATION_MM_S2:
        raise ConfigError(f"scenario.limits.max_acceleration_mm_s2 must be >= {MIN_ACCELERATION_MM_S2:g} mm/s^2, "
                          f"got {value!r}")
    return number


def _per_axis(value: Any, n_axes: int, context: str) -> list[float]:
    values = list(value) if isinstance(value, (list, tuple)) else [value] * n_axes
    if len(values) != n_axes:
        raise ConfigError(f"{context} needs 1 or {n_axes} values, got {len(values)}")
    return values


def _interpolator_config(section: Any) -> InterpolatorConfig:
    return build_config(InterpolatorConfig, section, "scenario.interpolator")


def _feed_override(section: Any) -> OverrideConfig | None:
    """The ``feed_override`` section: max_ratio, acceleration_share and ``schedule: [[t_s, ratio], ...]``."""
    if section is None:
        return None
    if not isinstance(section, Mapping):
        raise ConfigError(f"scenario.feed_override must be a mapping, got {section!r}")
    _refuse_unknown(section, ("max_ratio", "acceleration_share", "schedule"), "scenario.feed_override")
    values = {k: v for k, v in section.items() if k != "schedule"}
    schedule = section.get("schedule") or []
    if not isinstance(schedule, (list, tuple)) or not all(
            isinstance(row, (list, tuple)) and len(row) == 2 for row in schedule):
        raise ConfigError(f"scenario.feed_override.schedule must be a list of [t_s, ratio] pairs, got {schedule!r}")
    values["schedule_times_s"] = tuple(row[0] for row in schedule)
    values["schedule_ratios"] = tuple(row[1] for row in schedule)
    try:
        return build_config(OverrideConfig, values, "scenario.feed_override")
    except ConfigError as err:
        raise ConfigError(f"scenario.feed_override.{err}") from err


def _servos(section: Any, plant: PlantConfig) -> tuple[ServoConfig, ...]:
    """One ServoConfig per axis: the section's defaults, then ``axes: {x: {...}}`` overrides.

    ``follow_spindle: true`` gives every servo the plant's spindle schedule (the speed the CNC commands,
    :func:`_commanded_spindle`), so a law designed for the spindle speed follows it on line.
    """
    if not isinstance(section, Mapping):
        raise ConfigError(f"scenario.servo must be a mapping, got {section!r}")
    axes = plant.axes
    defaults = {k: v for k, v in section.items() if k not in ("axes", "follow_spindle")}
    follow = section.get("follow_spindle", False)
    if not isinstance(follow, bool):
        raise ConfigError(f"scenario.servo.follow_spindle must be true or false, got {follow!r}")
    if follow:
        defaults.update(_commanded_spindle(plant))
    per_axis = section.get("axes", {}) or {}
    if not isinstance(per_axis, Mapping) or not all(isinstance(v, Mapping) for v in per_axis.values()):
        raise ConfigError(f"scenario.servo.axes must map axis names to mappings (e.g. {{x: {{law: pid}}}}), "
                          f"got {per_axis!r}")
    unknown = sorted(set(per_axis) - set(axes))
    if unknown:
        raise ConfigError(f"scenario.servo.axes.{unknown[0]}: unknown axis; axes are {list(axes)}")
    servos = tuple(
        ServoConfig.from_mapping({"axis_name": axis, **merge(defaults, per_axis.get(axis, {}))},
                                 f"scenario.servo[{axis}]")
        for axis in axes
    )
    if follow:
        _check_flutes(servos, plant)
    return servos


def _plant_spindle(plant: PlantConfig) -> VelocityLoopOptions:
    """The plant's spindle: its velocity_loop section; a model without one is an error naming it."""
    if plant.velocity_loop is None:
        raise ConfigError(f"scenario.servo.follow_spindle needs a plant with a spindle (a velocity_loop section: "
                          f"models paper002, paper003), got plant model {plant.model!r}")
    return plant.velocity_loop


def _commanded_spindle(plant: PlantConfig) -> dict[str, tuple[float, ...]]:
    """The plant's spindle speed over the run as a servo's schedule: its speed from 0 s, then each change."""
    loop = _plant_spindle(plant)
    return {"spindle_schedule_t_s": (0.0, *loop.spindle_schedule_t_s),
            "spindle_schedule_rpm": (loop.spindle_rpm, *loop.spindle_schedule_rpm)}


def _check_flutes(servos: tuple[ServoConfig, ...], plant: PlantConfig) -> None:
    """A law that follows the spindle must count the plant's flutes, or its f_d is not the plant's."""
    flutes = _plant_spindle(plant).flutes
    for servo in servos:
        law_flutes = getattr(servo.law_config(), "flutes", flutes)
        if law_flutes != flutes:
            raise ConfigError(f"scenario.servo[{servo.axis_name}].law_params.flutes must be the plant's "
                              f"velocity_loop.flutes ({flutes}) with follow_spindle, got {law_flutes}")


def _cross_axis(raw: Mapping[str, Any]) -> dict[str, Any]:
    """The estimator, compensator and force-regulator sections (None when absent); a compensator needs an
    estimator, a force regulator a plant that cuts."""
    out: dict[str, Any] = {}
    for key, settings in (("estimator", EstimatorSettings), ("compensator", CompensatorSettings)):
        section = raw.get(key)
        out[key] = None if section is None else settings.from_mapping(_section(raw, key), f"scenario.{key}")
    section = raw.get("force_regulator")
    out["force_regulator"] = None if section is None else ForceRegulatorSettings.from_mapping(
        _section(raw, "force_regulator"), "scenario.force_regulator")
    if out["compensator"] is not None and out["estimator"] is None:
        raise ConfigError("scenario.compensator learns from the contour error: it needs a scenario.estimator "
                          "section too (e.g. estimator: {method: window})")
    return out
