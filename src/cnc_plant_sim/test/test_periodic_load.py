"""The periodic load at the plant input: the same as stepping the bare plant with u − A sin(φ + θ), the
spindle schedule's phase continuous across a live change, and refusals that change nothing."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_plant_sim.models.periodic_load import (
    PeriodicLoadConfig,
    PeriodicLoadPlant,
    SpindleFields,
    schedule_from,
    set_spindle_rpm,
)
from cnc_plant_sim.models.plant import PlantConfig, make_plant
from cnc_plant_sim.models.velocity_loop import VelocityLoopOptions, VelocityLoopPlant

DT_S = 0.01
LOAD = {"amplitude": 60.0, "spindle_rpm": 300.0, "flutes": 2, "phases_rad": [0.0, 1.0]}


def _plant(load: dict | None = None) -> object:
    config = {"model": "paper000", "axes": ["x", "y"], "seed": 3}
    return make_plant({**config, "periodic_load": load} if load else config)


@pytest.mark.parametrize("commands", [(0.0, 0.0), (40.0, -25.0)])
def test_the_loaded_plant_is_the_bare_plant_stepped_with_the_load_taken_from_its_input(commands: tuple) -> None:
    loaded, bare, unloaded = _plant(LOAD), _plant(), _plant()
    assert isinstance(loaded, PeriodicLoadPlant)
    for plant in (loaded, bare, unloaded):
        plant.reset()
    for k in range(60):
        t_s, f_hz = k * DT_S, 10.0  # 300 rpm x 2 flutes / 60
        d = [60.0 * math.sin(2 * math.pi * f_hz * t_s + theta) for theta in (0.0, 1.0)]
        loaded.step(commands, DT_S)
        unloaded.step(commands, DT_S)
        bare.step([u - di for u, di in zip(commands, d)], DT_S)
        np.testing.assert_allclose(loaded.positions_m(), bare.positions_m(), rtol=0, atol=1e-15)
    assert np.max(np.abs(loaded.positions_m() - unloaded.positions_m())) > 1e-6, "the load moves the axes"
    assert "periodic_load" in loaded.describe()


def test_no_amplitude_leaves_the_plant_unwrapped() -> None:
    assert not isinstance(_plant({**LOAD, "amplitude": 0.0}), PeriodicLoadPlant)


def test_a_live_change_keeps_the_phase_continuous_and_a_speed_at_nyquist_changes_nothing() -> None:
    plant = _plant(LOAD)
    plant.reset()
    for _ in range(37):
        plant.step([0.0, 0.0], DT_S)
    before = plant.schedule.phase_rad(plant.time_s)
    assert set_spindle_rpm(plant, 450.0, DT_S) == 1
    assert plant.schedule.phase_rad(plant.time_s) == pytest.approx(before, abs=1e-12)
    assert plant.schedule.frequency_hz(plant.time_s + DT_S) == pytest.approx(15.0)
    assert plant.schedule.frequency_hz(plant.time_s - DT_S) == pytest.approx(10.0)
    kept = plant.schedule
    with pytest.raises(ConfigError, match=r"spindle_rpm must be in \(0, 1500\) rpm .* got 1500"):
        set_spindle_rpm(plant, 1500.0, DT_S)
    assert plant.schedule is kept


def test_schedule_from_replaces_what_follows_the_change() -> None:
    schedule = PeriodicLoadConfig(spindle_rpm=600.0, spindle_schedule_t_s=(1.0, 2.0),
                                  spindle_schedule_rpm=(900.0, 1200.0)).schedule()
    changed = schedule_from(schedule, 1.5, 5.0)
    assert changed.start_times_s == (0.0, 1.0, 1.5) and changed.frequencies_hz == (20.0, 30.0, 5.0)
    assert changed.phase_rad(1.5) == pytest.approx(schedule.phase_rad(1.5))
    assert schedule_from(schedule, 1.0, 7.0).frequencies_hz == (20.0, 7.0)


def test_a_velocity_loop_plant_follows_the_live_speed_too_and_a_plant_without_a_load_refuses() -> None:
    plant = make_plant({"model": "paper002", "axes": ["x"]})
    assert isinstance(plant, VelocityLoopPlant)
    assert set_spindle_rpm(plant, 1800.0, 0.001) == 1 and plant.schedule.frequencies_hz[-1] == pytest.approx(60.0)
    with pytest.raises(ConfigError, match="no periodic disturbance"):
        set_spindle_rpm(_plant(), 300.0, DT_S)


@pytest.mark.parametrize(("values", "message"), [
    ({"amplitude": -1.0}, r"periodic_load.amplitude must be in \[0.0, 1000000.0\], got -1.0"),
    ({"phases_rad": [0.0, 7.0]}, r"periodic_load.phases_rad\[1\] must be in \[-2pi, 2pi\], got 7.0"),
    ({"flutes": 1.5}, "periodic_load.flutes must be an integer"),
    ({"spindle_schedule_t_s": [0.0], "spindle_schedule_rpm": [100.0]}, r"spindle_schedule_t_s\[0\] must be > 0"),
    ({"spindle_schedule_t_s": [1.0], "spindle_schedule_rpm": []}, "one entry per spindle_schedule_t_s"),
    ({"amplitud": 1.0}, "unknown key"),
])
def test_a_bad_section_is_refused_naming_the_option_the_bound_and_the_value(values: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        PlantConfig.from_mapping({"model": "paper000", "periodic_load": values})


@pytest.mark.parametrize("config, context", [(PeriodicLoadConfig, "periodic_load"),
                                             (VelocityLoopOptions, "velocity_loop")])
@pytest.mark.parametrize(("values", "message"), [
    ({"flutes": 2.5}, r"{}.flutes must be an integer in \[1, 1000\], got 2.5"),
    ({"flutes": 0}, r"{}.flutes must be in \[1, 1000\], got 0"),
    ({"spindle_schedule_t_s": [0.0], "spindle_schedule_rpm": [100.0]}, r"{}.spindle_schedule_t_s\[0\] must be > 0"),
    ({"spindle_schedule_t_s": [1.0, 0.5], "spindle_schedule_rpm": [1, 2]},
     r"{}.spindle_schedule_t_s\[1\] must be > 1, got 0.5"),
    ({"spindle_schedule_t_s": [1.0], "spindle_schedule_rpm": [0.0]}, r"{}.spindle_schedule_rpm\[0\] must be > 0"),
])
def test_both_spindle_sections_share_one_declaration_and_one_check(config: type, context: str, values: dict,
                                                                   message: str) -> None:
    assert issubclass(config, SpindleFields)
    with pytest.raises(ConfigError, match=message.format(context)):
        config(**values)


def test_the_shared_fields_build_the_same_schedule_in_both_sections() -> None:
    fields = {"spindle_rpm": 900, "flutes": np.int64(3), "spindle_schedule_t_s": [0.5], "spindle_schedule_rpm": [1200]}
    load, loop = PeriodicLoadConfig(**fields), VelocityLoopOptions(**fields)
    assert load.flutes == loop.flutes == 3 and type(loop.flutes) is int
    for schedule in (load.schedule(), loop.schedule()):
        assert (schedule.start_times_s, schedule.frequencies_hz) == ((0.0, 0.5), (45.0, 60.0))
    assert loop.schedule().frequency_hz(0.6) == pytest.approx(1200 * 3 / 60)
