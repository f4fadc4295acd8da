"""A multi-axis feed-drive plant with the paper's random parameter variation.

Plant models come from the registry :data:`PLANTS` by name; each gives the
nominal :class:`~cnc_plant_sim.axis.AxisConfig` of every requested axis.

``paper000``
    Paper 000, Table 2: X has K = 28.35 BLU/s per DAC unit, τ = 0.055 s and the
    Eq. (15) X friction (``paper000_x``); Y has K = 28.96, τ = 0.056 s and the Y
    friction (``paper000_y``). The paper has no Z axis: a Z axis, if asked for,
    **uses Y's parameters and Y's friction** (our choice). BLU = 10 µm, no
    drive saturation (the controller's 8-bit output saturates instead). Axis
    names are matched case-insensitively (``x``/``X``). ``axis_overrides``
    may change any :class:`AxisConfig` key of an axis.
``custom``
    Every axis is given fully in ``axis_overrides`` (at least
    ``gain_blu_s_per_dac`` and ``time_constant_s``; the friction defaults to
    ``none``).

Variation: :func:`make_plant` draws, once per run and per axis in axis order,
three numbers from ``numpy.random.default_rng(seed)``: a gain factor
``1 + U(−gain_pct, gain_pct)/100``, a time-constant factor ``1 +
U(−time_constant_pct, time_constant_pct)/100`` and a friction scale ``1 +
U(−friction_pct, friction_pct)/100`` (in that order). Same seed, same plant;
:meth:`Plant.reset` keeps the drawn parameters.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from cnc_contour_control.config import build_config, require_choice, require_range
from cnc_contour_control.errors import ConfigError, FaultError

from cnc_plant_sim.axis import AxisConfig, FeedDriveAxis, _require_int_at_least

#: Largest allowed variation [%] (K and τ must stay positive).
MAX_VARIATION_PCT = 50.0


@dataclass(frozen=True)
class VariationConfig:
    """Half-widths [%] of the uniform random variation drawn once per run.

    Parameters
    ----------
    gain_pct, time_constant_pct, friction_pct : float
        In [0, 50]; the paper uses 5, 5 and 8.
    """

    gain_pct: float = 5.0
    time_constant_pct: float = 5.0
    friction_pct: float = 8.0

    def __post_init__(self) -> None:
        for name in ("gain_pct", "time_constant_pct", "friction_pct"):
            require_range(name, getattr(self, name), 0.0, MAX_VARIATION_PCT, context="variation")


#: A plant model: config -> nominal axis configs, one per ``config.axes``.
PlantModel = Callable[["PlantConfig"], tuple[AxisConfig, ...]]


@dataclass(frozen=True)
class PlantConfig:
    """Validated description of a plant.

    Parameters
    ----------
    model : str
        Name in :data:`PLANTS`.
    axes : tuple of str
        Axis names in command order; unique, non-empty.
    variation : VariationConfig or Mapping
        Random variation half-widths (a mapping is validated into a config).
    seed : int
        Seed of ``numpy.random.default_rng``, >= 0.
    substeps : int
        Sub-steps per plant step for every axis without its own ``substeps``, >= 1.
    axis_overrides : Mapping[str, Mapping]
        Per axis name, :class:`AxisConfig` keys replacing the model's nominal values.
    """

    model: str = "paper000"
    axes: tuple[str, ...] = ("x", "y")
    variation: VariationConfig = field(default_factory=VariationConfig)
    seed: int = 0
    substeps: int = 1
    axis_overrides: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        require_choice("model", self.model, PLANTS)
        object.__setattr__(self, "axes", _checked_axes(self.axes))
        if isinstance(self.variation, Mapping):
            variation = build_config(VariationConfig, self.variation, context="variation")
            object.__setattr__(self, "variation", variation)
        elif not isinstance(self.variation, VariationConfig):
            raise ConfigError(f"variation must be a mapping, got {self.variation!r}")
        _require_int_at_least("seed", self.seed, 0)
        _require_int_at_least("substeps", self.substeps, 1)
        object.__setattr__(self, "axis_overrides", _checked_overrides(self.axis_overrides, self.axes))
        self.nominal_axes()

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], context: str = "plant") -> PlantConfig:
        """Build from a mapping; unknown keys are an error listing the valid ones."""
        return build_config(cls, mapping, context=context)

    def nominal_axes(self) -> tuple[AxisConfig, ...]:
        """The model's axis configs before the random variation."""
        return PLANTS[self.model](self)


def _checked_axes(axes: Any) -> tuple[str, ...]:
    if isinstance(axes, str) or not isinstance(axes, Sequence) or not axes:
        raise ConfigError(f"axes must be a non-empty list of names, got {axes!r}")
    names = tuple(axes)
    for name in names:
        if not isinstance(name, str) or not name:
            raise ConfigError(f"axes must hold non-empty strings, got {name!r}")
    if len(set(names)) != len(names):
        raise ConfigError(f"axes must be unique, got {list(names)}")
    return names


def _checked_overrides(overrides: Any, axes: tuple[str, ...]) -> dict[str, dict[str, Any]]:
    if overrides is None:
        return {}
    if not isinstance(overrides, Mapping):
        raise ConfigError(f"axis_overrides must be a mapping, got {overrides!r}")
    checked: dict[str, dict[str, Any]] = {}
    for name, values in overrides.items():
        if name not in axes:
            raise ConfigError(f"axis_overrides.{name}: unknown axis; valid axes are {list(axes)}")
        if not isinstance(values, Mapping):
            raise ConfigError(f"axis_overrides.{name} must be a mapping, got {values!r}")
        if "name" in values:
            raise ConfigError(f"axis_overrides.{name}.name: the name comes from axes")
        checked[name] = dict(values)
    return checked


def _axis_config(config: PlantConfig, name: str, base: Mapping[str, Any]) -> AxisConfig:
    values = {"substeps": config.substeps, **base, **config.axis_overrides.get(name, {}), "name": name}
    return build_config(AxisConfig, values, context=f"axis_overrides.{name}")


#: Paper 000, Table 2 and Eq. (15); Z copies Y (the paper has no Z).
PAPER000_AXES: dict[str, dict[str, Any]] = {
    "x": {"gain_blu_s_per_dac": 28.35, "time_constant_s": 0.055, "friction": "paper000_x"},
    "y": {"gain_blu_s_per_dac": 28.96, "time_constant_s": 0.056, "friction": "paper000_y"},
    "z": {"gain_blu_s_per_dac": 28.96, "time_constant_s": 0.056, "friction": "paper000_y"},
}


def paper000(config: PlantConfig) -> tuple[AxisConfig, ...]:
    """Nominal axes of paper 000 (X, Y; Z = Y)."""
    axes = []
    for name in config.axes:
        base = PAPER000_AXES.get(name.lower())
        if base is None:
            raise ConfigError(f"axes: paper000 has axes {sorted(PAPER000_AXES)}, got {name!r}")
        axes.append(_axis_config(config, name, base))
    return tuple(axes)


def custom(config: PlantConfig) -> tuple[AxisConfig, ...]:
    """Axes given fully by ``axis_overrides``."""
    for name in config.axes:
        given = config.axis_overrides.get(name, {})
        for key in ("gain_blu_s_per_dac", "time_constant_s"):
            if key not in given:
                raise ConfigError(f"axis_overrides.{name}.{key} is required for model 'custom'")
    return tuple(_axis_config(config, name, {}) for name in config.axes)


#: Plant models by name.
PLANTS: dict[str, PlantModel] = {"paper000": paper000, "custom": custom}


def _draw(rng: np.random.Generator, nominal: AxisConfig, variation: VariationConfig) -> AxisConfig:
    """One axis with K, τ and the friction scale drawn uniformly within the variation."""
    gain = 1.0 + rng.uniform(-variation.gain_pct, variation.gain_pct) / 100.0
    tau = 1.0 + rng.uniform(-variation.time_constant_pct, variation.time_constant_pct) / 100.0
    fric = 1.0 + rng.uniform(-variation.friction_pct, variation.friction_pct) / 100.0
    return dataclasses.replace(
        nominal,
        gain_blu_s_per_dac=nominal.gain_blu_s_per_dac * float(gain),
        time_constant_s=nominal.time_constant_s * float(tau),
        friction_scale=nominal.friction_scale * float(fric),
    )


class Plant:
    """Several independent feed-drive axes stepped together.

    Parameters
    ----------
    config : PlantConfig
        The plant; the random variation is drawn here, once.
    """

    command_unit = "dac"

    def __init__(self, config: PlantConfig) -> None:
        self.config = config
        self.nominal_configs = config.nominal_axes()
        rng = np.random.default_rng(config.seed)
        self.axis_configs = tuple(_draw(rng, c, config.variation) for c in self.nominal_configs)
        self.axes = tuple(FeedDriveAxis(c) for c in self.axis_configs)
        self.axis_names = tuple(config.axes)

    def reset(self, positions_m: Sequence[float] | None = None) -> None:
        """Put every axis at rest, at ``positions_m`` (shape (n,), m) or at 0."""
        if positions_m is None:
            positions_m = [0.0] * len(self.axes)
        self._check_length("positions_m", positions_m)
        for axis, position in zip(self.axes, positions_m):
            axis.reset(float(position), 0.0)

    def step(self, commands: Sequence[float], dt_s: float) -> None:
        """Hold ``commands`` (shape (n,), DAC units, axis order) for ``dt_s`` [s].

        Raises
        ------
        FaultError
            On a wrong count, a non-finite command or a bad ``dt_s``; no axis moves then.
        """
        self._check_length("commands", commands)
        if not _all_finite(commands):
            self._check_commands(commands)
        if not (dt_s > 0.0 and dt_s < math.inf):  # also refuses NaN
            raise FaultError(f"plant: dt_s must be finite and > 0, got {dt_s!r}")
        for axis, command in zip(self.axes, commands):
            axis.step(command, dt_s)

    def _check_commands(self, commands: Sequence[float]) -> None:
        """Raise :class:`FaultError` naming the first axis whose command is not a finite number."""
        for axis, command in zip(self.axes, commands):
            if not _is_finite_number(command):
                raise FaultError(f"axis {axis.name}: command must be finite, got {command!r}")

    def _check_length(self, name: str, values: Sequence[float]) -> None:
        if len(values) != len(self.axes):
            raise FaultError(
                f"plant: {name} must have {len(self.axes)} entries {list(self.axis_names)}, "
                f"got {len(values)}"
            )

    def positions_m(self) -> npt.NDArray[np.float64]:
        """Axis positions, shape (n,), m."""
        return np.array([axis.position_m for axis in self.axes])

    def velocities_m_s(self) -> npt.NDArray[np.float64]:
        """Axis velocities, shape (n,), m/s."""
        return np.array([axis.velocity_m_s for axis in self.axes])

    def friction_forces(self) -> npt.NDArray[np.float64]:
        """Friction applied in the last sub-step, shape (n,), DAC units."""
        return np.array([axis.friction_force for axis in self.axes])

    def describe(self) -> dict[str, Any]:
        """The plant as drawn (plain types, for the run record)."""
        return {
            "model": self.config.model,
            "seed": self.config.seed,
            "command_unit": self.command_unit,
            "variation": dataclasses.asdict(self.config.variation),
            "axes": {a.name: _describe_axis(a, n) for a, n in zip(self.axes, self.nominal_configs)},
        }


def _all_finite(values: Sequence[float]) -> bool:
    """True if every value is a finite number (one C-level sum; an overflow gives False too)."""
    try:
        total = sum(values, 0.0)
    except TypeError:
        return False
    return total - total == 0.0  # NaN for a NaN or an infinity


def _is_finite_number(value: Any) -> bool:
    try:
        return math.isfinite(value)
    except TypeError:
        return False


def _describe_axis(axis: FeedDriveAxis, nominal: AxisConfig) -> dict[str, Any]:
    drawn = axis.config
    return {
        "gain_blu_s_per_dac": drawn.gain_blu_s_per_dac,
        "nominal_gain_blu_s_per_dac": nominal.gain_blu_s_per_dac,
        "time_constant_s": drawn.time_constant_s,
        "nominal_time_constant_s": nominal.time_constant_s,
        "friction": drawn.friction,
        "friction_params": dict(drawn.friction_params),
        "friction_scale": drawn.friction_scale,
        "breakaway_positive_dac": axis.friction.breakaway_positive,
        "breakaway_negative_dac": axis.friction.breakaway_negative,
        "blu_m": drawn.blu_m,
        "substeps": drawn.substeps,
        "command_limit_dac": drawn.command_limit_dac,
    }


def make_plant(config: PlantConfig | Mapping[str, Any]) -> Plant:
    """Build a :class:`Plant` from a config or a mapping (validated)."""
    if not isinstance(config, PlantConfig):
        config = PlantConfig.from_mapping(config)
    return Plant(config)
