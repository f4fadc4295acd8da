"""Plants behind one protocol, built by name from a registry of factories.

A plant is anything that keeps :class:`Plant`: axis names in command order,
a command unit, ``reset(positions_m)``, ``step(commands, dt_s)`` holding the
commands over ``dt_s`` (zero-order hold), ``positions_m()`` and
``velocities_m_s()`` (SI, axis order), ``forces_n()`` (the process force per
axis in N, or None when the model has none) and ``describe()`` (the plant as
drawn, plain types, for the run record).

:data:`PLANTS` maps a model name to a :class:`PlantEntry`: the model's own
section of the plant config (its name and its frozen config class, fields
declared with :func:`~cnc_contour_control.core.params.param`, as a law's
``law_params``), a factory from a validated :class:`PlantConfig` and a check
of the model's own keys. A plant config holds the shared keys and its
model's section only; another model's section, or a key no section has, is a
:class:`ConfigError` naming the key and the model. The entries:

=====================  ==================  =========================================================
model                  section             plant
=====================  ==================  =========================================================
``paper000``           ``variation``       feed drives (:mod:`~cnc_plant_sim.models.feed_drives`),
                                           Table 2's axes, Eq. 15's friction
``custom``             ``variation``       feed drives with the axes given in ``axis_overrides``
``paper001``           ``mass_friction``   mass-friction axes (:mod:`~cnc_plant_sim.models.mass_friction`)
``paper002``,          ``velocity_loop``   velocity-commanded axes (:mod:`~cnc_plant_sim.models.velocity_loop`)
``paper003``
=====================  ==================  =========================================================

A new plant (a cutting process, an inner velocity loop) is a module with a
class keeping :class:`Plant` and one line in :data:`PLANTS`; a model whose
options are new adds its section to :data:`MODEL_SECTIONS` and a field of
:class:`PlantConfig`. :func:`make_plant` builds any entry; with machine faults
(``faults``) it wraps it in a :class:`~cnc_plant_sim.models.machine_faults.FaultedPlant`,
which also offers ``tool_positions_m()`` (any plant's tool position:
:func:`~cnc_plant_sim.models.machine_faults.tool_positions_m`, the positions without faults).
With a cutting process (``cutting``) the model is first wrapped in a
:class:`~cnc_plant_sim.process.cutting.CuttingPlant` (the process behind the feed axis;
:func:`~cnc_plant_sim.process.cutting.cutting_force_n` reads its force).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import param
from cnc_plant_sim.models.axis import AxisConfig, _require_int_at_least
from cnc_plant_sim.models.feed_drives import (
    FEED_DRIVE_MODELS,
    MAX_VARIATION_PCT,
    FeedDrivePlant,
    VariationConfig,
)
from cnc_plant_sim.models.machine_faults import FaultedPlant, MachineFaults
from cnc_plant_sim.models.mass_friction import (
    MassFrictionAxisConfig,
    MassFrictionOptions,
    MassFrictionPlant,
    paper001_axes,
)
from cnc_plant_sim.models.periodic_load import PeriodicLoadConfig, periodic_load_plant
from cnc_plant_sim.models.velocity_loop import (
    VelocityLoopAxisConfig,
    VelocityLoopOptions,
    VelocityLoopPlant,
    velocity_loop_axes,
)
from cnc_plant_sim.process.cutting import CuttingConfig, CuttingPlant

__all__ = ["MAX_VARIATION_PCT", "MODEL_SECTIONS", "PLANTS", "FeedDrivePlant", "Plant", "PlantConfig",
           "PlantEntry", "VariationConfig", "make_plant"]

#: The models' own sections of a plant config: name -> its config class (a model's entry names one).
MODEL_SECTIONS: dict[str, type] = {
    "variation": VariationConfig,
    "mass_friction": MassFrictionOptions,
    "velocity_loop": VelocityLoopOptions,
}


@runtime_checkable
class Plant(Protocol):
    """What every plant model offers (SI units at the interface, commands in ``command_unit``).

    Attributes
    ----------
    axis_names : tuple of str
        Axis names in command order.
    command_unit : str
        Unit of the commands ``step`` takes (``"dac"``).
    """

    axis_names: tuple[str, ...]
    command_unit: str

    def reset(self, positions_m: Sequence[float] | None = None) -> None:
        """At rest at ``positions_m`` (shape (n,), m; None: 0), keeping any drawn parameters."""

    def step(self, commands: Sequence[float], dt_s: float) -> None:
        """Hold ``commands`` (shape (n,)) for ``dt_s`` [s]; a FaultError leaves every axis where it was."""

    def positions_m(self) -> npt.NDArray[np.float64]:
        """Axis positions, shape (n,), m (a fresh array)."""

    def velocities_m_s(self) -> npt.NDArray[np.float64]:
        """Axis velocities, shape (n,), m/s (a fresh array)."""

    def state(self) -> tuple[list[float], list[float]]:
        """Positions [m] and velocities [m/s] as lists in axis order: what one tick reads (cheaper than arrays)."""

    def forces_n(self) -> npt.NDArray[np.float64] | None:
        """Process force per axis, shape (n,), N; None when the model knows no force."""

    def describe(self) -> dict[str, Any]:
        """The plant as built (plain types, for the run record)."""


@dataclass(frozen=True)
class PlantConfig:
    """Validated description of a plant.

    Parameters
    ----------
    model : str
        Name in :data:`PLANTS`.
    axes : tuple of str
        Axis names in command order; unique, non-empty.
    variation : VariationConfig or Mapping or None
        The feed drives' section (``paper000``, ``custom``): random variation half-widths.
    seed : int
        Seed of ``numpy.random.default_rng`` (the feed drives' variation), >= 0.
    substeps : int
        Sub-steps per plant step for every axis without its own ``substeps``, >= 1.
    axis_overrides : Mapping[str, Mapping]
        Per axis name, keys of the model's axis config (``PLANTS[model].axis_config``,
        :class:`AxisConfig` for feed drives) replacing the model's nominal values.
    mass_friction : MassFrictionOptions or Mapping or None
        The mass-friction model's section (``paper001``): length unit and cutting load.
    velocity_loop : VelocityLoopOptions or Mapping or None
        The velocity-loop models' section (``paper002``, ``paper003``; :mod:`cnc_plant_sim.models.velocity_loop`):
        spindle, flutes, spindle schedule and encoder.
    faults : MachineFaults or Mapping
        Machine faults between motor and tool (any model; :mod:`cnc_plant_sim.models.machine_faults`).
    cutting : CuttingConfig or Mapping
        A cutting process behind one axis (any model; :mod:`cnc_plant_sim.process.cutting`).
    periodic_load : PeriodicLoadConfig or Mapping
        A periodic load A sin(2π f_d t + θ) at the plant input (any model; :mod:`cnc_plant_sim.models.periodic_load`).

    Of the model sections (:data:`MODEL_SECTIONS`) only the model's own
    (``PLANTS[model].section``) may be given; it is built from its defaults
    when absent, the others stay None (:meth:`options` gives the model's).
    """

    model: str = param("paper000", description="plant model (registry name)", read_only=True)
    axes: tuple[str, ...] = param(("x", "y"), description="axis names, in command order", read_only=True)
    variation: VariationConfig | None = param(None, read_only=True,
                                              description="random variation of the drawn parameters (feed drives)")
    seed: int = param(0, low=0, description="seed of the parameter variation", read_only=True)
    substeps: int = param(1, low=1, description="integration sub-steps per sample", read_only=True)
    axis_overrides: Mapping[str, Mapping[str, Any]] = param(default_factory=dict, read_only=True,
                                                            description="per-axis model keys replacing the nominal")
    mass_friction: MassFrictionOptions | None = param(None, read_only=True,
                                                      description="options of the mass-friction plant (paper001)")
    velocity_loop: VelocityLoopOptions | None = param(None, read_only=True,
                                                      description="options of the velocity-loop plants "
                                                                  "(paper002, paper003)")
    faults: MachineFaults = param(default_factory=MachineFaults, read_only=True,
                                  description="machine faults between motor and tool (backlash, squareness, ...)")
    cutting: CuttingConfig = param(default_factory=CuttingConfig, read_only=True,
                                   description="cutting process behind the feed axis (turning: paper 004)")
    periodic_load: PeriodicLoadConfig = param(default_factory=PeriodicLoadConfig, read_only=True,
                                              description="periodic load at the plant input (tooth passing)")

    def __post_init__(self) -> None:
        require_choice("model", self.model, PLANTS)
        object.__setattr__(self, "axes", _checked_axes(self.axes))
        section = PLANTS[self.model].section
        _refuse_other_sections(self.model, {name: getattr(self, name) for name in MODEL_SECTIONS})
        object.__setattr__(self, section, _model_section(self.model, section, getattr(self, section)))
        if not isinstance(self.faults, MachineFaults):
            object.__setattr__(self, "faults", MachineFaults.from_mapping(self.faults, "faults"))
        self.faults.check_axes(self.axes)
        if not isinstance(self.cutting, CuttingConfig):
            object.__setattr__(self, "cutting", CuttingConfig.from_mapping(self.cutting, "cutting"))
        if not isinstance(self.periodic_load, PeriodicLoadConfig):
            object.__setattr__(self, "periodic_load", PeriodicLoadConfig.from_mapping(self.periodic_load))
        if self.cutting.active and self.cutting.feed_axis not in self.axes:
            raise ConfigError(f"cutting.feed_axis must be one of the axes {list(self.axes)}, "
                              f"got {self.cutting.feed_axis!r}")
        _require_int_at_least("seed", self.seed, 0)
        _require_int_at_least("substeps", self.substeps, 1)
        object.__setattr__(self, "axis_overrides", _checked_overrides(self.axis_overrides, self.axes))
        PLANTS[self.model].check(self)

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], context: str = "plant") -> PlantConfig:
        """Build from a mapping; an unknown key (or another model's section) is an error naming it and the model."""
        if not isinstance(mapping, Mapping):
            raise ConfigError(f"{context} must be a mapping, got {mapping!r}")
        model = mapping.get("model", PlantConfig.model)
        entry = PLANTS.get(model) if isinstance(model, str) else None
        if entry is not None:  # an unknown model: the config's error lists the valid ones
            valid = sorted(_SHARED_KEYS | {entry.section})
            unknown = sorted(set(mapping) - set(valid))
            if unknown and unknown[0] in MODEL_SECTIONS:
                raise ConfigError(f"{context}.{unknown[0]}: {other_section_error(model, unknown[0])}")
            if unknown:
                raise ConfigError(f"{context}.{unknown[0]}: unknown key of plant model {model!r}; "
                                  f"valid keys are {valid}")
        return build_config(cls, mapping, context=context)

    def options(self) -> Any:
        """The model's own section (a validated instance of ``PLANTS[model].options``)."""
        return getattr(self, PLANTS[self.model].section)

    def nominal_axes(self) -> tuple[AxisConfig, ...]:
        """The model's feed-drive axis configs before the random variation.

        Raises
        ------
        ConfigError
            If the model is not made of feed-drive axes.
        """
        axes_of = FEED_DRIVE_MODELS.get(self.model)
        if axes_of is None:
            raise ConfigError(f"plant model {self.model!r} has no feed-drive axes; "
                              f"feed-drive models are {sorted(FEED_DRIVE_MODELS)}")
        return axes_of(self.axes, self.axis_overrides, self.substeps)


def _models_with(section: str) -> list[str]:
    """The models whose own section is ``section``."""
    return sorted(name for name, entry in PLANTS.items() if entry.section == section)


def other_section_error(model: str, section: str) -> str:
    """Why ``section`` (another model's) is refused for ``model`` (the error's text after the key)."""
    return (f"a section of plant model(s) {_models_with(section)}, not of model {model!r} "
            f"(whose section is {PLANTS[model].section})")


def _refuse_other_sections(model: str, sections: Mapping[str, Any]) -> None:
    """A section given (not None) that is not ``model``'s own is an error naming it and the model."""
    for name, value in sections.items():
        if value is not None and name != PLANTS[model].section:
            raise ConfigError(f"{name}: {other_section_error(model, name)}")


def _model_section(model: str, section: str, value: Any) -> Any:
    """``model``'s section validated (an instance of its class; None: its defaults), errors naming the model."""
    options = MODEL_SECTIONS[section]
    if value is None:
        return options()
    if isinstance(value, options):
        return value
    if not isinstance(value, Mapping):
        raise ConfigError(f"{section} must be a mapping, got {value!r} (plant model {model!r})")
    try:
        return build_config(options, value, context=section)
    except ConfigError as err:
        raise ConfigError(f"{err} (plant model {model!r})") from err


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


@dataclass(frozen=True)
class PlantEntry:
    """One plant model of the registry.

    Attributes
    ----------
    section : str
        The model's own section of a plant config, a key of :data:`MODEL_SECTIONS`
        (``variation``, ``mass_friction``, ``velocity_loop``).
    build : Callable
        Validated :class:`PlantConfig` -> a fresh plant (random draws made here).
    check : Callable
        Validates the model's own use of the config (known axes, complete
        overrides), raising :class:`ConfigError`; called by ``PlantConfig``.
    axis_config : type
        The config class whose keys ``axis_overrides`` takes (the plant node declares them).
    """

    section: str
    build: Callable[[PlantConfig], Plant]
    check: Callable[[PlantConfig], object]
    axis_config: type = AxisConfig

    def __post_init__(self) -> None:
        require_choice("section", self.section, MODEL_SECTIONS)

    @property
    def options(self) -> type:
        """The config class of the model's section (fields declared with ``param``)."""
        return MODEL_SECTIONS[self.section]


def _feed_drives(config: PlantConfig) -> FeedDrivePlant:
    """Feed-drive axes of ``config.model``, varied by ``config.variation`` with ``config.seed``."""
    return FeedDrivePlant(config.model, config.nominal_axes(), config.options(), config.seed)


def _paper001_axes(config: PlantConfig) -> tuple[MassFrictionAxisConfig, ...]:
    """Paper 001's Table 1 axes of ``config`` with its overrides."""
    return paper001_axes(config.axes, config.axis_overrides)


def _mass_friction(config: PlantConfig) -> MassFrictionPlant:
    """Paper 001's mass-friction axes (no random variation: the paper draws none)."""
    return MassFrictionPlant(config.model, _paper001_axes(config), config.options(), config.substeps)


def _velocity_loop_axes(config: PlantConfig) -> tuple[VelocityLoopAxisConfig, ...]:
    """The velocity-loop axes of ``config.model`` with its overrides."""
    return velocity_loop_axes(config.model, config.axes, config.axis_overrides)


def _velocity_loop(config: PlantConfig) -> VelocityLoopPlant:
    """Velocity-commanded axes (papers 002, 003; no random variation)."""
    return VelocityLoopPlant(config.model, _velocity_loop_axes(config), config.options(), config.substeps)


#: Plant models by name.
PLANTS: dict[str, PlantEntry] = {
    "paper000": PlantEntry("variation", _feed_drives, PlantConfig.nominal_axes),
    "custom": PlantEntry("variation", _feed_drives, PlantConfig.nominal_axes),
    "paper001": PlantEntry("mass_friction", _mass_friction, _paper001_axes, MassFrictionAxisConfig),
    "paper002": PlantEntry("velocity_loop", _velocity_loop, _velocity_loop_axes, VelocityLoopAxisConfig),
    "paper003": PlantEntry("velocity_loop", _velocity_loop, _velocity_loop_axes, VelocityLoopAxisConfig),
}
#: The keys every plant config takes, whatever its model (beside the model's own section).
_SHARED_KEYS = frozenset(f.name for f in dataclasses.fields(PlantConfig)) - set(MODEL_SECTIONS)


def make_plant(config: PlantConfig | Mapping[str, Any]) -> Plant:
    """Build the plant of ``config`` (a config or a mapping, validated) from :data:`PLANTS`."""
    if not isinstance(config, PlantConfig):
        config = PlantConfig.from_mapping(config)
    plant = periodic_load_plant(PLANTS[config.model].build(config), config.periodic_load)
    if config.cutting.active:
        plant = CuttingPlant(plant, config.cutting)
    return FaultedPlant(plant, config.faults) if config.faults.active else plant
