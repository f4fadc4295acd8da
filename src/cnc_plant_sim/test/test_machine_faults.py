"""Machine faults on the tool side: the play operator, the fault model against its formula, validation."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_plant_sim.models.machine_faults import FaultedPlant, MachineFaults, apply_faults, play, tool_positions_m
from cnc_plant_sim.models.plant import PlantConfig, make_plant

NO_VARIATION = {"gain_pct": 0, "time_constant_pct": 0, "friction_pct": 0}


def test_play_follows_through_the_dead_band() -> None:
    backlash_m = 10e-6
    table = 0.0
    path = [3e-6, 8e-6, 20e-6, 14e-6, 9e-6, 0.0]
    seen = []
    for motor in path:
        table = play(motor, table, backlash_m)
        seen.append(table)
    np.testing.assert_allclose(seen, [0.0, 3e-6, 15e-6, 15e-6, 14e-6, 5e-6], atol=1e-18)


def test_fault_model_matches_its_formula() -> None:
    faults = MachineFaults.from_mapping({"squareness_urad": 100.0, "axes": {
        "x": {"scale_ppm": 200.0}, "y": {"cyclic_amplitude_um": 2.0, "cyclic_pitch_mm": 4.0}}})
    table = np.array([[0.01, 0.02], [-0.003, 0.0071]])
    y = table[:, 1] + 2e-6 * np.sin(2 * math.pi * table[:, 1] / 4e-3)
    x = table[:, 0] * (1 + 200e-6) + 100e-6 * y
    np.testing.assert_allclose(apply_faults(table, faults, ("x", "y")), np.column_stack((x, y)), atol=1e-15)


def test_motor_side_unchanged_and_tool_side_faulted() -> None:
    config = {"model": "paper000", "variation": NO_VARIATION}
    clean, faulted = make_plant(config), make_plant({**config, "faults": {"axes": {"x": {"backlash_um": 20.0}}}})
    assert isinstance(faulted, FaultedPlant) and not isinstance(clean, FaultedPlant)
    for plant in (clean, faulted):
        plant.reset([0.0, 0.0])
        for _ in range(50):
            plant.step([60.0, 40.0], 0.01)
    np.testing.assert_array_equal(clean.positions_m(), faulted.positions_m())
    np.testing.assert_array_equal(tool_positions_m(clean), clean.positions_m())
    assert np.all(clean.positions_m() > 1e-3)  # both axes moved forwards, far beyond the dead band
    lag = faulted.positions_m() - tool_positions_m(faulted)
    np.testing.assert_allclose(lag, [10e-6, 0.0], atol=1e-15)
    assert faulted.describe()["faults"]["axes"]["x"]["backlash_um"] == 20.0


@pytest.mark.parametrize("faults, message", [
    ({"axes": {"z": {"backlash_um": 1.0}}}, "faults.axes.z: unknown axis"),
    ({"axes": {"x": {"backlash_um": -1.0}}}, "backlash_um"),
    ({"axes": {"x": {"bogus": 1.0}}}, "bogus"),
    ({"squareness_urad": 5.0, "squareness_axes": ["x", "x"]}, "two different axis names"),
    ({"squareness_urad": 5.0, "squareness_axes": ["x", "z"]}, "squareness_axes must be axes of the plant"),
    (3, "faults must be a mapping"),
])
def test_bad_faults_are_refused(faults: object, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        PlantConfig.from_mapping({"model": "paper000", "faults": faults})


def test_no_faults_is_inactive() -> None:
    assert not PlantConfig.from_mapping({"model": "paper000"}).faults.active
    assert MachineFaults.from_mapping({"axes": {"x": {"cyclic_pitch_mm": 2.0}}}).active is False
