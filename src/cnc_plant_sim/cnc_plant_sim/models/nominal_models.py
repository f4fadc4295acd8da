"""The nominal plant P_n a disturbance canceller needs, derived from a plant config (ROS-free).

P_n maps one axis's drive input (the servo's command: DAC, N) to the axis
velocity in the law's units (counts/s), sampled at the servo's period. It is
derived, not identified: the continuous transfer function the plant model
integrates, without friction and before any random variation, discretised
with a zero-order hold (:func:`~cnc_contour_control.disturbance.stack_loop.zoh_model`,
:func:`scipy.signal.cont2discrete`), as the servo
holds its command. Per model (:data:`VELOCITY_MODELS`)::

    paper000, custom   K/(τ s + 1)   [BLU/s per DAC]  (feed_drives: position K/(s(τs+1)))
    paper001           1/(m s + B)   [L/s per N]      (mass_friction, Eq. 18 without f_c, f_s)

scaled to counts/s by ``counts_per_m`` and the model's length unit. The ZOH
of a strictly proper P gives numerator[0] = 0 (one sample of delay), which
the canceller needs. ``test_nominal_models`` checks the model against the
plant simulated without friction (same samples to 1e-9).
"""
from __future__ import annotations

from collections.abc import Callable

from cnc_contour_control.core.config import require_choice, require_positive
from cnc_contour_control.core.velocity_models import DiscreteVelocityModel
from cnc_contour_control.disturbance.stack_loop import zoh_model
from cnc_plant_sim.models.feed_drives import FeedDrivePlant
from cnc_plant_sim.models.mass_friction import LENGTH_UNITS, paper001_axes
from cnc_plant_sim.models.plant import PlantConfig

#: A plant model's continuous P(s) for one axis: (config, axis, drawn) -> (numerator, denominator) in s,
#: input drive units, output metres per second; ``drawn``: the axis after the config's random variation.
ContinuousModel = Callable[[PlantConfig, str, bool], tuple[tuple[float, ...], tuple[float, ...]]]


def _feed_drive(config: PlantConfig, axis: str, drawn: bool) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """K/(τs + 1) in m/s per DAC (the nominal axis, or as the plant draws it with the config's seed)."""
    axes = FeedDrivePlant(config.model, config.nominal_axes(), config.options(), config.seed).axis_configs \
        if drawn else config.nominal_axes()
    drive = next(a for a in axes if a.name == axis)
    return (drive.gain_blu_s_per_dac * drive.blu_m,), (drive.time_constant_s, 1.0)


def _mass_friction(config: PlantConfig, axis: str, drawn: bool) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """1/(m s + B) in m/s per N (Table 1 with the overrides, in the model's length unit; no variation)."""
    mass = next(a for a in paper001_axes(config.axes, config.axis_overrides) if a.name == axis)
    return (LENGTH_UNITS[config.options().length_unit],), (mass.mass, mass.viscous)


#: Continuous drive-input -> velocity models by plant model name.
VELOCITY_MODELS: dict[str, ContinuousModel] = {
    "paper000": _feed_drive,
    "custom": _feed_drive,
    "paper001": _mass_friction,
}


def continuous_velocity_model(config: PlantConfig, axis: str,
                              drawn: bool = False) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """P(s) of ``axis`` [m/s per drive unit], polynomials in s (highest power first); ``drawn``: as the plant
    draws it (the true plant of a run), else nominal (what a model knows)."""
    require_choice("plant.model", config.model, VELOCITY_MODELS, "nominal model")
    require_choice("axis", axis, config.axes, "nominal model")
    return VELOCITY_MODELS[config.model](config, axis, drawn)


def drive_velocity_model(config: PlantConfig, axis: str, counts_per_m: float,
                         sample_time_s: float) -> DiscreteVelocityModel:
    """P_n of ``axis``: drive units -> counts/s, ZOH at ``sample_time_s`` [s], in z⁻¹ (numerator[0] = 0)."""
    require_positive("counts_per_m", counts_per_m)
    require_positive("sample_time_s", sample_time_s)
    b, a = zoh_model(*continuous_velocity_model(config, axis), counts_per_m, sample_time_s)
    return DiscreteVelocityModel(tuple(float(v) for v in b), tuple(float(v) for v in a), sample_time_s)


def canceller_model_params(model: DiscreteVelocityModel) -> dict[str, object]:
    """``model`` as a stacked law's ``model_numerator``, ``model_denominator``, ``model_sample_time_s``."""
    return {"model_numerator": list(model.numerator), "model_denominator": list(model.denominator),
            "model_sample_time_s": model.sample_time_s}
