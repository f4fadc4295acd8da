"""The cutting section of any plant: the turning process behind the feed axis (core, no ROS)."""
from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import config_values
from cnc_plant_sim.models.plant import PlantConfig, make_plant
from cnc_plant_sim.process.cutting import CuttingConfig, CuttingPlant, cutting_force_n
from cnc_plant_sim.process.turning import TurningProcess

TURNING: dict[str, Any] = {"process": "turning", "feed_axis": "z", "depth_schedule": [[0.0, 1.0], [0.05, 2.0]]}


def plant_config(**changes: Any) -> PlantConfig:
    """A paper-003 velocity loop on x, z cutting along z."""
    return PlantConfig.from_mapping({"model": "paper003", "axes": ["x", "z"], "velocity_loop": {"spindle_rpm": 0},
                                     "cutting": TURNING, **changes})


def test_the_force_is_the_turning_process_under_the_steps_mean_feed_velocity() -> None:
    config = plant_config()
    plant = make_plant(config)
    drives = make_plant(PlantConfig.from_mapping({"model": "paper003", "axes": ["x", "z"],
                                                  "velocity_loop": {"spindle_rpm": 0}}))
    process = TurningProcess(config.cutting.turning)
    plant.reset([0.0, 0.0])
    drives.reset([0.0, 0.0])
    forces, expected = [], []
    for k in range(100):
        commands = [0.0, 0.002 * min(1.0, k / 20)]                     # m/s: the z axis speeds up to 120 mm/min
        before = drives.state()[1][1]
        drives.step(commands, 0.001)
        plant.step(commands, 0.001)
        expected.append(process.step(0.5 * (before + drives.state()[1][1]), 0.001))
        forces.append(cutting_force_n(plant))
    assert forces == expected
    assert plant.positions_m().tolist() == drives.positions_m().tolist(), "the process does not load the axes"
    assert forces[40] < forces[49] and forces[60] > 1.5 * forces[49], "the depth stepped 1 -> 2 mm at 50 ms"


def test_a_plant_without_the_section_does_not_cut_and_reset_restarts_the_process() -> None:
    assert cutting_force_n(make_plant({"model": "paper000", "axes": ["x", "y"]})) is None
    plant = make_plant(plant_config())
    plant.reset([0.0, 0.0])
    for _ in range(50):
        plant.step([0.0, 0.002], 0.001)
    assert cutting_force_n(plant) > 0.0
    plant.reset([0.0, 0.0])
    assert cutting_force_n(plant) == 0.0 and plant.inner.velocities_m_s().tolist() == [0.0, 0.0]


def test_machine_faults_and_a_cut_together_keep_both() -> None:
    plant = make_plant(plant_config(faults={"axes": {"z": {"backlash_um": 5.0}}}))
    plant.reset([0.0, 0.0])
    for _ in range(30):
        plant.step([0.0, 0.002], 0.001)
    assert cutting_force_n(plant) > 0.0
    assert plant.tool_positions_m()[1] < plant.positions_m()[1], "the table lags the motor by the play"
    assert "cutting" in plant.describe() and "faults" in plant.describe()


def test_the_section_splits_a_schedule_of_pairs_and_gives_the_node_flat_lists() -> None:
    config = CuttingConfig.from_mapping(TURNING)
    assert config.depth_schedule_t_s == (0.0, 0.05) and config.depth_schedule_mm == (1.0, 2.0)
    assert config.turning.depth_schedule == ((0.0, 1.0), (0.05, 2.0))
    values = config.values()
    assert "depth_schedule" not in values["turning"] and values["depth_schedule_mm"] == [1.0, 2.0]
    assert CuttingConfig.from_mapping(values) == config
    assert CuttingConfig.from_mapping(config_values(config)) == config, "the derived schedule given back is fine"
    assert not CuttingConfig().active and config.active


@pytest.mark.parametrize(("changes", "message"), [
    ({"process": "drilling"}, "process must be one of"),
    ({"feed_axis": "y"}, "cutting.feed_axis must be one of the axes ['x', 'z'], got 'y'"),
    ({"depth_schedule": [[0.0, 1.0], [0.0, 2.0]]}, "depth_schedule[1].t_s must be > 0.0 (sorted), got 0.0"),
    ({"depth_schedule": [[0.0, -1.0]]}, "depth_schedule[0].depth_mm"),
    ({"depth_schedule": [[0.0]]}, "list of [t_s, depth_mm] pairs"),
    ({"depth_schedule": None, "depth_schedule_t_s": [0, 1], "depth_schedule_mm": [1, 2, 3]},
     "one depth per time (2), got 3"),
    ({"depth_schedule_mm": [1.0, 2.0]}, "cutting.depth_schedule and cutting.depth_schedule_mm both give"),
    ({"turning": {"depth_schedule": [[0, 1]]}}, "give cutting.depth_schedule"),
    ({"turning": {"spindle_rpm": 0.0}}, "spindle_rpm"),
])
def test_a_bad_section_is_refused_naming_the_option_and_the_value(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError) as err:
        plant_config(cutting={k: v for k, v in {**TURNING, **changes}.items() if v is not None})
    assert message in str(err.value)


def test_the_wrapper_refuses_a_feed_axis_the_inner_plant_lacks() -> None:
    inner = make_plant({"model": "paper000", "axes": ["x", "y"]})
    with pytest.raises(ConfigError, match=r"feed_axis must be one of the plant's axes \['x', 'y'\], got 'z'"):
        CuttingPlant(inner, CuttingConfig.from_mapping(TURNING))
    assert np.isfinite(inner.positions_m()).all()
