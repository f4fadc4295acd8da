"""Independent feed-drive axes stepped together, with the paper's random parameter variation.

The nominal axes come from a model in :data:`FEED_DRIVE_MODELS`:

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

Variation: :class:`FeedDrivePlant` draws, once per run and per axis in axis
order, three numbers from ``numpy.random.default_rng(seed)``: a gain factor
``1 + U(−gain_pct, gain_pct)/100``, a time-constant factor ``1 +
U(−time_constant_pct, time_constant_pct)/100`` and a friction scale ``1 +
U(−friction_pct, friction_pct)/100`` (in that order). Same seed, same plant;
:meth:`FeedDrivePlant.reset` keeps the drawn parameters.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param
from cnc_plant_sim.models.axis import AxisConfig, FeedDriveAxis
from cnc_plant_sim.models.step_checks import check_length, check_step

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

    gain_pct: float = param(5.0, unit="%", low=0.0, high=MAX_VARIATION_PCT, read_only=True,
                            description="half-width of the drive gain K's variation")
    time_constant_pct: float = param(5.0, unit="%", low=0.0, high=MAX_VARIATION_PCT, read_only=True,
                                     description="half-width of the time constant's variation")
    friction_pct: float = param(8.0, unit="%", low=0.0, high=MAX_VARIATION_PCT, read_only=True,
                                description="half-width of the friction's variation")

    def __post_init__(self) -> None:
        check_ranges(self, "variation")


#: Nominal axes of a feed-drive model: (axis names, per-axis overrides, default substeps) -> axis configs.
AxesModel = Callable[[Sequence[str], Mapping[str, Mapping[str, Any]], int], tuple[AxisConfig, ...]]


def _axis_config(name: str, base: Mapping[str, Any], overrides: Mapping[str, Mapping[str, Any]],
                 substeps: int) -> AxisConfig:
    values = {"substeps": substeps, **base, **overrides.get(name, {}), "name": name}
    return build_config(AxisConfig, values, context=f"axis_overrides.{name}")


#: Paper 000, Table 2 and Eq. (15); Z copies Y (the paper has no Z).
PAPER000_AXES: dict[str, dict[str, Any]] = {
    "x": {"gain_blu_s_per_dac": 28.35, "time_constant_s": 0.055, "friction": "paper000_x"},
    "y": {"gain_blu_s_per_dac": 28.96, "time_constant_s": 0.056, "friction": "paper000_y"},
    "z": {"gain_blu_s_per_dac": 28.96, "time_constant_s": 0.056, "friction": "paper000_y"},
}


def paper000_axes(names: Sequence[str], overrides: Mapping[str, Mapping[str, Any]],
                  substeps: int) -> tuple[AxisConfig, ...]:
    """Nominal axes of paper 000 (X, Y; Z = Y)."""
    axes = []
    for name in names:
        base = PAPER000_AXES.get(name.lower())
        if base is None:
            raise ConfigError(f"axes: paper000 has axes {sorted(PAPER000_AXES)}, got {name!r}")
        axes.append(_axis_config(name, base, overrides, substeps))
    return tuple(axes)


def custom_axes(names: Sequence[str], overrides: Mapping[str, Mapping[str, Any]],
                substeps: int) -> tuple[AxisConfig, ...]:
    """Axes given fully by ``overrides``."""
    for name in names:
        given = overrides.get(name, {})
        for key in ("gain_blu_s_per_dac", "time_constant_s"):
            if key not in given:
                raise ConfigError(f"axis_overrides.{name}.{key} is required for model 'custom'")
    return tuple(_axis_config(name, {}, overrides, substeps) for name in names)


#: Feed-drive models by name (each an entry of :data:`cnc_plant_sim.models.plant.PLANTS`).
FEED_DRIVE_MODELS: dict[str, AxesModel] = {"paper000": paper000_axes, "custom": custom_axes}


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



class FeedDrivePlant:
    """Several independent feed-drive axes stepped together (a :class:`~cnc_plant_sim.models.plant.Plant`).

    Parameters
    ----------
    model : str
        The model's name (for :meth:`describe`).
    nominal : tuple of AxisConfig
        The axes before the variation, in command order.
    variation : VariationConfig
        Half-widths of the variation, drawn here, once.
    seed : int
        Seed of ``numpy.random.default_rng``.
    """

    command_unit = "dac"

    def __init__(self, model: str, nominal: tuple[AxisConfig, ...], variation: VariationConfig, seed: int) -> None:
        self.model, self.variation, self.seed = model, variation, seed
        self.nominal_configs = nominal
        rng = np.random.default_rng(seed)
        self.axis_configs = tuple(_draw(rng, c, variation) for c in nominal)
        self.axes = tuple(FeedDriveAxis(c) for c in self.axis_configs)
        self.axis_names = tuple(c.name for c in nominal)

    def reset(self, positions_m: Sequence[float] | None = None) -> None:
        """Put every axis at rest, at ``positions_m`` (shape (n,), m) or at 0."""
        if positions_m is None:
            positions_m = [0.0] * len(self.axes)
        check_length(self.axis_names, "positions_m", positions_m)
        for axis, position in zip(self.axes, positions_m):
            axis.reset(float(position), 0.0)

    def step(self, commands: Sequence[float], dt_s: float) -> None:
        """Hold ``commands`` (shape (n,), DAC units, axis order) for ``dt_s`` [s].

        Raises
        ------
        FaultError
            On a wrong count, a non-finite command or a bad ``dt_s``; no axis moves then.
        """
        check_step(self.axis_names, commands, dt_s)
        for axis, command in zip(self.axes, commands):  # every command checked above: no axis re-checks
            axis.advance(command if type(command) is float else float(command), dt_s)

    def positions_m(self) -> npt.NDArray[np.float64]:
        """Axis positions, shape (n,), m."""
        return np.array([axis.position_m for axis in self.axes])

    def velocities_m_s(self) -> npt.NDArray[np.float64]:
        """Axis velocities, shape (n,), m/s."""
        return np.array([axis.velocity_m_s for axis in self.axes])

    def state(self) -> tuple[list[float], list[float]]:
        """Positions [m] and velocities [m/s] as lists in axis order (the per-tick read; nothing allocated in numpy)."""
        positions, velocities = [], []
        for axis in self.axes:  # one loop, no comprehension frames: this runs every tick
            position, velocity = axis.state_m()
            positions.append(position)
            velocities.append(velocity)
        return positions, velocities

    def forces_n(self) -> None:
        """None: the model's friction is in drive units, it knows no force in N."""
        return None

    def friction_forces(self) -> npt.NDArray[np.float64]:
        """Friction applied in the last sub-step, shape (n,), DAC units."""
        return np.array([axis.friction_force for axis in self.axes])

    def describe(self) -> dict[str, Any]:
        """The plant as drawn (plain types, for the run record)."""
        return {
            "model": self.model,
            "seed": self.seed,
            "command_unit": self.command_unit,
            "variation": dataclasses.asdict(self.variation),
            "axes": {a.name: _describe_axis(a, n) for a, n in zip(self.axes, self.nominal_configs)},
        }


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
