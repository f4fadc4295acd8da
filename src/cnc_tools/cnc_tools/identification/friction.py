"""Friction identification (paper 000, Section 2): constant-speed runs under P control.

One axis runs a straight line at a constant programmed speed ``V_r`` under a
pure P law ``u = K_p e`` (8-bit DAC: saturated at ±127, quantised to 1). In
steady state the drive ``dP/dt = K (u − F_d)`` gives Eq. (1) of the paper,
``e_ss = V_r/(K K_e K_p) + F_d/K_p``, hence Eq. (1a)::

    F_d = K_p e_ss − V_r / (K K_e)

Units (the plant's, see :mod:`cnc_plant_sim.models.axis`): ``e_ss`` and ``V_r`` in
servo counts and counts/s, ``K`` in BLU/s per DAC unit, ``K_e`` the encoder
gain in counts per BLU (``counts_per_m · blu_m``; 1 for paper 000, whose
servo counts are BLU), ``F_d`` and ``u`` in DAC units. ``K`` is the plant's
*nominal* gain, as an experimenter knows it from the drive's data: with the
random ±5 % gain variation the ``V_r/(K K_e)`` term is off by up to 5 %, which
is part of the run-to-run spread.

``e_ss`` is the mean following error over a window of the constant-speed part
of the reference: it starts ``settle_s`` after the ramp reaches ``V_r`` and
ends where the deceleration ramp starts. The 8-bit quantisation makes the
command toggle between neighbouring DAC levels, so ``e`` ripples; the mean
over the window is used, and ``quantisation_dac = mean(u) − K_p·mean(e)``
shows how much the rounding biases that mean (the estimate from ``mean(u)``
would be free of it). A window where the axis stops (stick-slip near V = 0),
drifts, or does not move at ``V_r`` is flagged, not hidden (:data:`STATUSES`).

The fitted curve has the form of Eq. (15) per branch: a quadratic in V up to
a break speed and a constant beyond (the break chosen by least squares). It
is written as a ``table`` friction (:class:`~cnc_plant_sim.models.friction.TableFriction`)
usable as a plant friction model or as a feedforward table.
"""
from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.config import require_choice, require_non_negative, require_positive
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.units import M_PER_MM
from cnc_plant_sim.models.friction import FrictionModel, make_friction
from cnc_tools.runs.scenario import Scenario, build_scenario

FloatArray = npt.NDArray[np.float64]

#: Speed magnitudes [mm/s], run in both directions; denser near 0 where the curve bends.
DEFAULT_SPEEDS_MM_S = (0.05, 0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 11.5, 13.0, 16.0, 20.0)
#: Paper 000's plant and servo hardware: T = 10 ms, 8-bit DAC, BLU = 10 µm, ±5 %/±5 %/±8 % variation.
DEFAULT_TEMPLATE: dict[str, Any] = {
    "sample_time_s": 0.01, "mode": "lockstep",
    "plant": {"model": "paper000", "axes": ["x", "y"],
              "variation": {"gain_pct": 5.0, "time_constant_pct": 5.0, "friction_pct": 8.0}},
    "limits": {"max_velocity_mm_min": 2000.0, "max_acceleration_mm_s2": 250.0},
    "servo": {"counts_per_m": 1.0e5, "output_limit": 127.0, "quantum": 1.0, "command_unit": "dac"},
}
#: Window statuses: ``steady`` is used for the curve; the others are reported.
STATUSES = ("steady", "stick-slip", "stuck")
#: Largest share of window samples in which the axis may stand still for ``steady``.
MAX_STOPPED_FRACTION = 0.05
#: Largest relative deviation of the measured mean speed from ``V_r`` for ``steady``.
MAX_SPEED_DEVIATION = 0.05
#: Largest change of ``K_p·mean(e)`` between the window's halves [DAC] for ``steady``.
MAX_DRIFT_DAC = 0.5
#: Extra cruise beyond ``settle_s + window_s`` [s] (keeps the window off the deceleration ramp).
CRUISE_MARGIN_S = 0.2
#: Speed [mm/s] of the scenario built to read the template's limits before the speeds are checked.
PROBE_SPEED_MM_S = 0.01
#: Simulated time after the program ends [s] (nothing is measured there).
RUN_TAIL_S = 0.1


@dataclass(frozen=True)
class IdentificationConfig:
    """What to run: axis, speeds, P gain, plants, averaging window.

    Parameters
    ----------
    axis : str
        Axis to identify (one of the template plant's axes).
    speeds_mm_s : tuple of float
        Speed magnitudes [mm/s], each > 0, distinct; both directions are run.
    kp_dac_per_count : float
        Gain of the P law [DAC units per servo count], > 0.
    seeds : tuple of int
        Seeds of the varied plants (the template's ±% variation), >= 0; the
        nominal plant (no variation) is always run as well.
    settle_s : float
        Time after the ramp reaches ``V_r`` before averaging starts [s], >= 0.
    window_s : float
        Averaging window [s], > 0 (at least 10 samples).
    """

    axis: str = "x"
    speeds_mm_s: tuple[float, ...] = DEFAULT_SPEEDS_MM_S
    kp_dac_per_count: float = 2.4
    seeds: tuple[int, ...] = (1, 2, 3, 4)
    settle_s: float = 1.0
    window_s: float = 2.0

    def __post_init__(self) -> None:
        speeds = tuple(require_positive(f"speeds_mm_s[{i}]", v) for i, v in enumerate(self.speeds_mm_s))
        if not speeds:
            raise ConfigError("speeds_mm_s must hold at least one speed, got []")
        if len(set(speeds)) != len(speeds):
            raise ConfigError(f"speeds_mm_s must be distinct, got {list(speeds)}")
        object.__setattr__(self, "speeds_mm_s", tuple(sorted(speeds)))
        require_positive("kp_dac_per_count", self.kp_dac_per_count)
        require_non_negative("settle_s", self.settle_s)
        require_positive("window_s", self.window_s)
        for i, seed in enumerate(self.seeds):
            if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
                raise ConfigError(f"seeds[{i}] must be an integer >= 0, got {seed!r}")
        if len(set(self.seeds)) != len(self.seeds):
            raise ConfigError(f"seeds must be distinct, got {list(self.seeds)}")

    @property
    def signed_speeds_mm_s(self) -> tuple[float, ...]:
        """Every speed in both directions, ascending [mm/s]."""
        return tuple(sorted([-v for v in self.speeds_mm_s] + list(self.speeds_mm_s)))


# =========================================================================== planning
@dataclass(frozen=True)
class SpeedRun:
    """One planned run: a plant (nominal or a seed) at one signed speed."""

    plant_label: str
    seed: int | None
    velocity_mm_s: float
    scenario: Scenario

    @property
    def label(self) -> str:
        """Folder name of the run, e.g. ``v+0.500``."""
        return f"v{self.velocity_mm_s:+.3f}"


@dataclass(frozen=True)
class AxisConstants:
    """What Eq. (1a) needs about the identified axis (nominal values).

    Attributes: ``gain_blu_s_per_dac`` K, ``encoder_counts_per_blu`` K_e,
    ``counts_per_m`` of the servo, ``friction`` the nominal model (Eq. 15 at scale 1).
    """

    axis: str
    axis_index: int
    gain_blu_s_per_dac: float
    encoder_counts_per_blu: float
    counts_per_m: float
    friction: FrictionModel


def base_mapping(template: Mapping[str, Any], config: IdentificationConfig) -> dict[str, Any]:
    """The template scenario with a P law on every axis (no feedforward, no per-axis servo overrides), no program."""
    raw = {k: copy.deepcopy(v) for k, v in template.items() if k not in ("program", "duration_s", "paper")}
    raw.get("plant", {}).pop("seed", None)  # the run's seed decides the plant
    servo = {k: v for k, v in dict(raw.get("servo", {})).items() if k != "axes"}
    servo.update({"law": "p", "law_params": {"kp": float(config.kp_dac_per_count)}, "ff1": 0.0, "ff2": 0.0})
    raw["servo"], raw["settle_s"] = servo, RUN_TAIL_S
    return raw


def run_mapping(base: Mapping[str, Any], config: IdentificationConfig, velocity_mm_s: float,
                seed: int | None) -> dict[str, Any]:
    """The scenario mapping of one run: a line along the axis long enough for ramp + settle + window."""
    raw = copy.deepcopy(dict(base))
    plant = raw.setdefault("plant", {})
    axes = list(plant.get("axes", ["x", "y"]))
    accel_mm_s2 = _axis_value(raw.get("limits", {}).get("max_acceleration_mm_s2", 1000.0), axes.index(config.axis))
    speed = abs(velocity_mm_s)
    length_mm = speed * (config.settle_s + config.window_s + CRUISE_MARGIN_S) + speed * speed / float(accel_mm_s2)
    end_mm = [0.0] * len(axes)
    end_mm[axes.index(config.axis)] = math.copysign(length_mm, velocity_mm_s)
    raw["program"] = {"axes": axes, "segments": [{"line": {"to_mm": end_mm, "feed_mm_min": speed * 60.0}}]}
    if seed is None:
        plant["variation"] = {"gain_pct": 0.0, "time_constant_pct": 0.0, "friction_pct": 0.0}
    raw["seed"] = 0 if seed is None else int(seed)
    raw["name"] = f"friction_id_{config.axis}_{'nominal' if seed is None else f'seed{seed}'}_{velocity_mm_s:+.3f}"
    return raw


def _axis_value(value: Any, index: int) -> float:
    return float(value[index] if isinstance(value, (list, tuple)) else value)


def axis_constants(scenario: Scenario, axis: str) -> AxisConstants:
    """K, K_e and the nominal friction of ``axis`` in a (template) scenario."""
    require_choice("axis", axis, scenario.axes)
    index = scenario.axes.index(axis)
    nominal = scenario.plant.nominal_axes()[index]
    counts_per_m = float(scenario.servos[index].counts_per_m)
    return AxisConstants(axis, index, float(nominal.gain_blu_s_per_dac), counts_per_m * float(nominal.blu_m),
                         counts_per_m, nominal.make_friction())


def plan_runs(template: Mapping[str, Any], config: IdentificationConfig) -> tuple[AxisConstants, list[SpeedRun]]:
    """Validate the speeds against the axis limits and build every run's scenario (nominal first).

    The limits are checked on the plant of the first seed (the template's
    variation) when there are seeds, else on the nominal plant.

    Raises
    ------
    ConfigError
        Naming ``axis`` if the plant has no such axis, or ``speeds_mm_s`` with the
        bound (``limits.max_velocity_mm_min`` or ``servo.output_limit``) a speed exceeds.
    """
    base = base_mapping(template, config)
    require_choice("axis", config.axis, tuple(base.get("plant", {}).get("axes", ("x", "y"))))
    probe_speed_mm_s = min(config.speeds_mm_s[0], PROBE_SPEED_MM_S)  # within any limit; the real speeds come next
    probe = build_scenario(run_mapping(base, config, probe_speed_mm_s, config.seeds[0] if config.seeds else None))
    constants = axis_constants(probe, config.axis)
    check_speeds(probe, constants, config)
    plants: list[tuple[str, int | None]] = [("nominal", None), *((f"seed_{s}", s) for s in config.seeds)]
    runs = [SpeedRun(label, seed, v, build_scenario(run_mapping(base, config, v, seed)))
            for label, seed in plants for v in config.signed_speeds_mm_s]
    return constants, runs


def check_speeds(scenario: Scenario, constants: AxisConstants, config: IdentificationConfig) -> None:
    """Refuse speeds beyond the axis's velocity limit or needing more than the DAC range."""
    index = constants.axis_index
    limit_mm_s = scenario.limits.max_velocity_m_s[index] / M_PER_MM
    headroom_mm_s = dac_speed_limit_mm_s(scenario, constants)
    for i, speed in enumerate(config.speeds_mm_s):
        if speed > limit_mm_s:
            raise ConfigError(f"speeds_mm_s[{i}] must be <= limits.max_velocity_mm_min/60 = {limit_mm_s:.3f} mm/s "
                              f"on axis {constants.axis}, got {speed!r}")
        if speed > headroom_mm_s:
            raise ConfigError(f"speeds_mm_s[{i}] must be <= {headroom_mm_s:.3f} mm/s, the largest speed whose "
                              f"command stays within servo.output_limit = {scenario.servos[index].output_limit:g} "
                              f"on axis {constants.axis} (with the plant variation), got {speed!r}")


def dac_speed_limit_mm_s(scenario: Scenario, constants: AxisConstants) -> float:
    """Largest speed [mm/s] whose steady command ``V/K + |F(V)|`` stays below the servo's output limit.

    The lowest gain and the highest friction scale the scenario's plant variation can draw count.
    """
    variation = scenario.plant.options()  # a feed drive's VariationConfig (the constants are its nominal axis's)
    gain = constants.gain_blu_s_per_dac * (1.0 - variation.gain_pct / 100.0)
    scale = 1.0 + variation.friction_pct / 100.0
    mm_per_blu = constants.encoder_counts_per_blu / constants.counts_per_m / M_PER_MM
    speeds = np.linspace(0.0, scenario.limits.max_velocity_m_s[constants.axis_index] / M_PER_MM, 2001)
    need = [s / mm_per_blu / gain + scale * max(abs(constants.friction.force(s)), abs(constants.friction.force(-s)))
            for s in speeds]
    inside = speeds[np.asarray(need) < scenario.servos[constants.axis_index].output_limit]
    return float(inside[-1]) if inside.size else 0.0


# =========================================================================== one run
@dataclass(frozen=True, eq=False)
class AxisTrace:
    """One run of the identified axis; arrays of shape (N,), SI units, command in DAC units."""

    time_s: FloatArray
    position_m: FloatArray
    reference_m: FloatArray
    reference_velocity_m_s: FloatArray
    command_dac: FloatArray


@dataclass(frozen=True)
class DrawnAxis:
    """The identified axis as the run's plant drew it (from ``Plant.describe()``)."""

    gain_blu_s_per_dac: float
    friction: FrictionModel
    friction_scale: float

    @classmethod
    def from_description(cls, plant: Mapping[str, Any], axis: str) -> DrawnAxis:
        """From the ``plant`` entry of a run summary (or ``Plant.describe()``)."""
        drawn = plant["axes"][axis]
        model = make_friction(drawn["friction"], drawn.get("friction_params") or {})
        scale = float(drawn["friction_scale"])
        return cls(float(drawn["gain_blu_s_per_dac"]), model.scaled(scale), scale)


@dataclass(frozen=True)
class FrictionPoint:
    """The identification at one signed speed on one plant (forces in DAC units).

    ``friction_dac`` is Eq. (1a) with the nominal K; ``friction_true_gain_dac``
    uses the gain the plant drew (only a simulation knows it); ``model_dac`` is
    the friction the plant ran (Eq. 15 times the drawn scale) at ``V_r``.
    """

    plant_label: str
    seed: int | None
    velocity_mm_s: float
    error_ss_counts: float
    ripple_counts: float
    friction_dac: float
    friction_true_gain_dac: float
    command_mean_dac: float
    quantisation_dac: float
    model_dac: float
    model_nominal_dac: float
    friction_scale: float
    measured_velocity_mm_s: float
    stopped_fraction: float
    drift_dac: float
    samples: int
    status: str

    @property
    def deviation_dac(self) -> float:
        """Identified minus the model the plant ran."""
        return self.friction_dac - self.model_dac


def window_mask(trace: AxisTrace, velocity_mm_s: float, settle_s: float) -> npt.NDArray[np.bool_]:
    """Samples of the constant-speed part, from ``settle_s`` after the ramp to the deceleration start."""
    cruise = np.nonzero(np.abs(trace.reference_velocity_m_s) >= abs(velocity_mm_s) * M_PER_MM * (1.0 - 1e-6))[0]
    if cruise.size == 0:
        raise FaultError(f"run at {velocity_mm_s:+g} mm/s: the reference never reaches the programmed speed")
    start_s, end_s = trace.time_s[cruise[0]] + settle_s, trace.time_s[cruise[-1]]
    mask = (trace.time_s >= start_s - 1e-9) & (trace.time_s <= end_s + 1e-9)
    if mask.sum() < 10:
        raise FaultError(f"run at {velocity_mm_s:+g} mm/s: only {int(mask.sum())} samples of constant speed "
                         f"after settle_s = {settle_s} s; at least 10 are needed")
    return mask


def classify(stopped_fraction: float, speed_ratio: float, drift_dac: float) -> str:
    """``stuck``, ``stick-slip`` or ``steady`` (see the thresholds at the top of the module)."""
    if stopped_fraction >= 0.99:
        return "stuck"
    steady = (stopped_fraction <= MAX_STOPPED_FRACTION and abs(speed_ratio - 1.0) <= MAX_SPEED_DEVIATION
              and abs(drift_dac) <= MAX_DRIFT_DAC)
    return "steady" if steady else "stick-slip"


def estimate_point(trace: AxisTrace, run: SpeedRun, constants: AxisConstants, drawn: DrawnAxis,
                   config: IdentificationConfig) -> FrictionPoint:
    """Eq. (1a) on the run's averaging window, with the window's steadiness checks."""
    mask = window_mask(trace, run.velocity_mm_s, config.settle_s)
    kp = config.kp_dac_per_count
    error = (trace.reference_m[mask] - trace.position_m[mask]) * constants.counts_per_m
    position, time_s = trace.position_m[mask], trace.time_s[mask]
    speed_counts_s = run.velocity_mm_s * M_PER_MM * constants.counts_per_m
    k_ke = constants.gain_blu_s_per_dac * constants.encoder_counts_per_blu
    true_k_ke = drawn.gain_blu_s_per_dac * constants.encoder_counts_per_blu
    measured_mm_s = (position[-1] - position[0]) / (time_s[-1] - time_s[0]) / M_PER_MM
    half = error.size // 2
    drift = kp * float(error[half:].mean() - error[:half].mean())
    stopped = float(np.mean(np.diff(position) == 0.0))
    error_ss, command = float(error.mean()), float(trace.command_dac[mask].mean())
    return FrictionPoint(
        run.plant_label, run.seed, run.velocity_mm_s, error_ss, float(error.std()),
        kp * error_ss - speed_counts_s / k_ke, kp * error_ss - speed_counts_s / true_k_ke,
        command, command - kp * error_ss, drawn.friction.force(run.velocity_mm_s),
        constants.friction.force(run.velocity_mm_s), drawn.friction_scale, measured_mm_s, stopped, drift,
        int(error.size), classify(stopped, measured_mm_s / run.velocity_mm_s, drift))
