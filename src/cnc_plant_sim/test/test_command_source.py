"""Tier 1: the plant's command source and the JointState field of each plant's command interface (no ROS)."""
from __future__ import annotations

import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_plant_sim.models.plant import PLANTS, make_plant
from cnc_plant_sim.run.command_source import COMMAND_INTERFACES, CommandSourceParams, command_interface


@pytest.mark.parametrize("model", sorted(PLANTS))
def test_every_plant_has_a_command_interface(model: str) -> None:
    if model == "custom":  # the feed drives of paper000 with axes given in full: the same builder, the same unit
        assert PLANTS["custom"].build is PLANTS["paper000"].build
        return
    plant = make_plant({"model": model, "axes": ["x", "y"]})
    assert command_interface(plant.command_unit) in ("effort", "velocity")


def test_velocity_commanded_plants_take_velocity_the_others_effort() -> None:
    assert command_interface("m/s") == "velocity"
    assert command_interface("dac") == command_interface("N") == "effort"


def test_an_unknown_unit_lists_the_known_ones() -> None:
    with pytest.raises(ConfigError, match=r"'rpm'.*\['N', 'dac', 'm/s'\]"):
        command_interface("rpm")
    assert sorted(COMMAND_INTERFACES) == ["N", "dac", "m/s"]


def test_params_default_to_axis_commands_and_refuse_an_unknown_source() -> None:
    assert CommandSourceParams().command_source == "axis_command"
    with pytest.raises(ConfigError, match="command_source"):
        CommandSourceParams(command_source="effort_controller")
