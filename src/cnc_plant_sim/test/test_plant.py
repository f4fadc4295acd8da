"""Plants: the protocol and the registry of factories; the feed drives' Table 2, variation, stepping, faults."""
from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import config_values, flat_specs
from cnc_plant_sim.models.axis import AxisConfig, FeedDriveAxis
from cnc_plant_sim.models.feed_drives import FEED_DRIVE_MODELS, FeedDrivePlant
from cnc_plant_sim.models.plant import MODEL_SECTIONS, PLANTS, Plant, PlantConfig, PlantEntry, make_plant

NO_VARIATION = {"gain_pct": 0, "time_constant_pct": 0, "friction_pct": 0}


def test_paper000_nominal_table2() -> None:
    plant = make_plant({"axes": ["x", "y", "z"], "variation": NO_VARIATION})
    axes = plant.describe()["axes"]
    assert (axes["x"]["gain_blu_s_per_dac"], axes["x"]["time_constant_s"]) == (28.35, 0.055)
    assert (axes["y"]["gain_blu_s_per_dac"], axes["y"]["time_constant_s"]) == (28.96, 0.056)
    assert axes["z"] == axes["y"]
    assert_allclose([axes["x"]["breakaway_positive_dac"], axes["x"]["breakaway_negative_dac"]],
                    [20.49, -18.27])
    assert plant.command_unit == "dac"
    assert plant.axis_names == ("x", "y", "z")


def test_same_seed_same_plant_other_seed_other_plant() -> None:
    first, again = make_plant({"seed": 7}), make_plant({"seed": 7})
    other = make_plant({"seed": 8})
    assert first.describe() == again.describe()
    assert first.describe()["axes"] != other.describe()["axes"]


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_draws_stay_within_the_variation(seed: int) -> None:
    plant = make_plant({"seed": seed, "variation": {"gain_pct": 5, "time_constant_pct": 5,
                                                    "friction_pct": 8}})
    for axis in plant.describe()["axes"].values():
        assert abs(axis["gain_blu_s_per_dac"] / axis["nominal_gain_blu_s_per_dac"] - 1) <= 0.05
        assert abs(axis["time_constant_s"] / axis["nominal_time_constant_s"] - 1) <= 0.05
        assert abs(axis["friction_scale"] - 1) <= 0.08


def test_drawn_friction_scale_reaches_the_axis() -> None:
    plant = make_plant({"seed": 3, "axes": ["x"]})
    scale = plant.describe()["axes"]["x"]["friction_scale"]
    assert_allclose(plant.axes[0].friction.breakaway_positive, 20.49 * scale)


def test_reset_keeps_the_drawn_parameters() -> None:
    plant = make_plant({"seed": 1})
    before = plant.describe()
    plant.step([60.0, -60.0], 0.01)
    plant.reset([0.01, 0.02])
    assert plant.describe() == before
    assert_allclose(plant.positions_m(), [0.01, 0.02])
    assert_allclose(plant.velocities_m_s(), [0.0, 0.0])


def test_plant_steps_like_its_axes() -> None:
    plant = make_plant({"seed": 4, "substeps": 3})
    twins = [FeedDriveAxis(c) for c in plant.axis_configs]
    commands = [[50.0, -40.0], [70.0, 10.0], [-30.0, 25.0]]
    for command in commands:
        plant.step(command, 0.01)
        for twin, u in zip(twins, command):
            twin.step(u, 0.01)
    assert plant.positions_m().shape == (2,)
    assert_allclose(plant.positions_m(), [t.position_m for t in twins], rtol=0, atol=0)
    assert_allclose(plant.velocities_m_s(), [t.velocity_m_s for t in twins], rtol=0, atol=0)
    assert_allclose(plant.friction_forces(), [t.friction_force for t in twins], rtol=0, atol=0)
    assert all(c.substeps == 3 for c in plant.axis_configs)


def test_bad_command_moves_no_axis() -> None:
    plant = make_plant({})
    plant.step([60.0, 60.0], 0.01)
    before = plant.positions_m()
    with pytest.raises(FaultError, match=r"axis y: command must be finite, got nan"):
        plant.step([60.0, math.nan], 0.01)
    with pytest.raises(FaultError, match=r"axis x: command must be finite, got 'fast'"):
        plant.step(["fast", 1.0], 0.01)
    with pytest.raises(FaultError, match=r"commands must have 2 entries \['x', 'y'\], got 3"):
        plant.step([1.0, 2.0, 3.0], 0.01)
    with pytest.raises(FaultError, match="dt_s must be finite and > 0, got 0"):
        plant.step([1.0, 2.0], 0)
    assert_allclose(plant.positions_m(), before, rtol=0, atol=0)


def test_custom_plant_and_overrides() -> None:
    plant = make_plant({
        "model": "custom", "axes": ["a"], "variation": NO_VARIATION,
        "axis_overrides": {"a": {"gain_blu_s_per_dac": 10.0, "time_constant_s": 0.02,
                                 "friction": "coulomb_viscous",
                                 "friction_params": {"coulomb_dac": 3.0}}},
    })
    assert plant.axis_configs[0] == AxisConfig("a", 10.0, 0.02, "coulomb_viscous", {"coulomb_dac": 3.0})
    paper = make_plant({"axes": ["X"], "variation": NO_VARIATION,
                        "axis_overrides": {"X": {"time_constant_s": 0.1}}})
    assert paper.axis_configs[0].time_constant_s == 0.1
    assert paper.axis_configs[0].friction == "paper000_x"


@pytest.mark.parametrize(("mapping", "message"), [
    ({"model": "paper999"},
     "model must be one of ['custom', 'paper000', 'paper001', 'paper002', 'paper003'], got 'paper999'"),
    ({"axes": ["x", "w"]}, "paper000 has axes ['x', 'y', 'z'], got 'w'"),
    ({"axes": ["x", "x"]}, "axes must be unique"),
    ({"axes": []}, "axes must be a non-empty list of names, got []"),
    ({"seed": -1}, "seed must be an integer >= 0, got -1"),
    ({"substeps": 0}, "substeps must be an integer >= 1, got 0"),
    ({"variation": {"gain_pct": 60}}, "variation.gain_pct must be in [0.0, 50.0], got 60"),
    ({"variation": {"friction_pct": -1}}, "variation.friction_pct must be in [0.0, 50.0], got -1"),
    ({"variation": {"noise_pct": 1}}, "variation.noise_pct: unknown key"),
    ({"axis_overrides": {"z": {}}}, "axis_overrides.z: unknown axis; valid axes are ['x', 'y']"),
    ({"axis_overrides": {"x": {"gain": 1}}}, "axis_overrides.x.gain: unknown key"),
    ({"axis_overrides": {"x": {"time_constant_s": 0}}}, "time_constant_s must be > 0, got 0"),
    ({"model": "custom", "axes": ["a"]},
     "axis_overrides.a.gain_blu_s_per_dac is required for model 'custom'"),
    ({"sead": 1}, "plant.sead: unknown key of plant model 'paper000'; valid keys are"),
    ({"model": "paper001", "flutes": 2}, "plant.flutes: unknown key of plant model 'paper001'; valid keys are"),
    ({"mass_friction": {"length_unit": "mm"}},
     "plant.mass_friction: a section of plant model(s) ['paper001'], not of model 'paper000' "
     "(whose section is variation)"),
    ({"model": "paper001", "variation": NO_VARIATION},
     "plant.variation: a section of plant model(s) ['custom', 'paper000'], not of model 'paper001'"),
    ({"model": "paper003", "velocity_loop": {"spindle": 0}},
     "velocity_loop.spindle: unknown key; valid keys are ['encoder_pulse_m', 'flutes', 'spindle_rpm', "
     "'spindle_schedule_rpm', 'spindle_schedule_t_s'] (plant model 'paper003')"),
])
def test_bad_plant_config(mapping: dict, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        make_plant(mapping)
    assert message in str(info.value)


def test_registry_names() -> None:
    assert set(PLANTS) == {"paper000", "custom", "paper001", "paper002", "paper003"}
    assert isinstance(make_plant(PlantConfig()), Plant)


@pytest.mark.parametrize("model", sorted(PLANTS))
def test_a_plant_config_holds_its_models_section_only(model: str) -> None:
    overrides = {"x": {"gain_blu_s_per_dac": 20.0, "time_constant_s": 0.05}} if model == "custom" else {}
    config = PlantConfig.from_mapping({"model": model, "axes": ["x"], "axis_overrides": overrides})
    entry = PLANTS[model]
    assert isinstance(config.options(), entry.options) and config.options() == entry.options()
    assert [name for name in MODEL_SECTIONS if getattr(config, name) is not None] == [entry.section]
    assert all(spec.info.description for spec in flat_specs(entry.options))
    values = config_values(config)
    assert values[entry.section] == config_values(entry.options())
    assert PlantConfig.from_mapping({k: v for k, v in values.items() if v is not None}) == config


@pytest.mark.parametrize("model", sorted(FEED_DRIVE_MODELS))  # paper001: test_mass_friction.py
def test_every_entry_keeps_the_protocol(model: str) -> None:
    overrides = {"x": {"gain_blu_s_per_dac": 20.0, "time_constant_s": 0.05}} if model == "custom" else {}
    plant = make_plant({"model": model, "axes": ["x"], "axis_overrides": overrides})
    assert isinstance(plant, Plant)
    plant.reset([0.001])
    plant.step([30.0], 0.01)
    assert plant.positions_m().shape == plant.velocities_m_s().shape == (1,)
    assert plant.velocities_m_s()[0] > 0.0
    assert plant.forces_n() is None  # the feed drives' friction is in DAC units: no force in N
    assert plant.describe()["model"] == model and plant.command_unit == "dac"


class ConstantSpeedPlant:
    """A plant of another kind: every axis moves at command·1 mm/s, and knows a force of 2·command N."""

    command_unit = "mm_s"

    def __init__(self, config: PlantConfig) -> None:
        self.axis_names = config.axes
        self.reset()

    def reset(self, positions_m=None) -> None:
        self._x = np.array(positions_m if positions_m is not None else [0.0] * len(self.axis_names), float)
        self._u = np.zeros(len(self.axis_names))

    def step(self, commands, dt_s: float) -> None:
        self._u = np.asarray(commands, float)
        self._x = self._x + self._u * 1e-3 * dt_s

    def positions_m(self) -> np.ndarray:
        return self._x.copy()

    def velocities_m_s(self) -> np.ndarray:
        return self._u * 1e-3

    def state(self) -> tuple[list[float], list[float]]:
        return self.positions_m().tolist(), self.velocities_m_s().tolist()

    def forces_n(self) -> np.ndarray:
        return 2.0 * self._u

    def describe(self) -> dict:
        return {"model": "constant_speed"}


def check_no_z(config: PlantConfig) -> None:
    if "z" in config.axes:
        raise ConfigError("axes: constant_speed has no z")


def test_a_plant_added_to_the_registry_is_built_by_make_plant() -> None:
    PLANTS["constant_speed"] = PlantEntry("variation", ConstantSpeedPlant, check_no_z)
    try:
        plant = make_plant({"model": "constant_speed", "axes": ["x", "y"]})
        assert isinstance(plant, Plant) and not isinstance(plant, FeedDrivePlant)
        plant.step([10.0, -5.0], 0.5)
        assert_allclose(plant.positions_m(), [5e-3, -2.5e-3])
        assert_allclose(plant.forces_n(), [20.0, -10.0])
        assert plant.state() == ([5e-3, -2.5e-3], [0.01, -0.005])
        with pytest.raises(ConfigError, match="constant_speed has no z"):
            make_plant({"model": "constant_speed", "axes": ["x", "z"]})
        with pytest.raises(ConfigError, match="plant model 'constant_speed' has no feed-drive axes"):
            PlantConfig(model="constant_speed").nominal_axes()
    finally:
        del PLANTS["constant_speed"]



def test_core_modules_do_not_import_rclpy() -> None:
    code = ("import sys, cnc_plant_sim.models.friction, cnc_plant_sim.models.axis, cnc_plant_sim.models.plant, "
            "cnc_contour_control.axis.servo, cnc_contour_control.laws; "
            "assert 'rclpy' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True, env=None)


def test_positions_are_fresh_arrays() -> None:
    plant = make_plant({})
    positions = plant.positions_m()
    positions[0] = 99.0
    assert plant.positions_m()[0] == 0.0
    assert isinstance(positions, np.ndarray)
