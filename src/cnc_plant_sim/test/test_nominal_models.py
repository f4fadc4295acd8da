"""P_n derived from a plant config is the plant itself without friction, sampled as the servo holds its command."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.laws.pdc_stack import PAPER000_X_MODEL
from cnc_plant_sim.models.nominal_models import continuous_velocity_model, drive_velocity_model
from cnc_plant_sim.models.plant import PlantConfig, make_plant

CASES = {
    "paper000": ({"model": "paper000", "axes": ["x", "y"], "variation": {"gain_pct": 0, "time_constant_pct": 0,
                                                                          "friction_pct": 0},
                  "axis_overrides": {"y": {"friction": "none"}}}, "y", 1.0e5, 0.01, 20.0),
    "paper001": ({"model": "paper001", "axes": ["x"], "mass_friction": {"length_unit": "mm"},
                  "axis_overrides": {"x": {"coulomb_n": 0.0, "stribeck_n": 0.0}}}, "x", 1.0e6, 0.001, 50.0),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_derived_model_is_the_frictionless_plant_sample_for_sample(name: str) -> None:
    mapping, axis, counts_per_m, dt_s, scale = CASES[name]
    config = PlantConfig.from_mapping(mapping)
    model = drive_velocity_model(config, axis, counts_per_m, dt_s)
    assert model.numerator[0] == 0.0 and model.denominator[0] == 1.0
    plant = make_plant(config)
    plant.reset()
    index = config.axes.index(axis)
    u = np.random.default_rng(1).normal(0.0, scale, 150)
    measured = []
    for value in u:
        commands = [0.0] * len(config.axes)
        commands[index] = float(value)
        plant.step(commands, dt_s)
        measured.append(plant.velocities_m_s()[index] * counts_per_m)
    predicted = signal.lfilter(model.numerator, model.denominator, np.append(u, 0.0))[1:]
    np.testing.assert_allclose(measured, predicted, rtol=1e-9, atol=1e-9 * np.max(np.abs(predicted)))


def test_the_stacks_default_model_is_paper_000s_x_drive_and_the_drawn_plant_differs_from_the_nominal() -> None:
    config = PlantConfig.from_mapping({"model": "paper000", "axes": ["x", "y"], "seed": 1})
    model = drive_velocity_model(config, "x", 1.0e5, 0.01)
    np.testing.assert_allclose(model.numerator, PAPER000_X_MODEL[0], rtol=1e-12)
    np.testing.assert_allclose(model.denominator, PAPER000_X_MODEL[1], rtol=1e-12)
    assert continuous_velocity_model(config, "x", drawn=True) != continuous_velocity_model(config, "x")


def test_a_plant_without_a_drive_model_is_refused_naming_the_valid_ones() -> None:
    with pytest.raises(ConfigError, match=r"plant.model must be one of \['custom', 'paper000', 'paper001'\]"):
        drive_velocity_model(PlantConfig.from_mapping({"model": "paper002", "axes": ["x"]}), "x", 1.0, 0.001)
