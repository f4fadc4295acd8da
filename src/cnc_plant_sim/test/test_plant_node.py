"""Tier 2: the plant node in-process with real rclpy: lockstep ticks and refusal of bad commands."""
from __future__ import annotations

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import flat_specs
from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import AxisCommand
from cnc_plant_sim.models.plant import MODEL_SECTIONS, PLANTS
from cnc_plant_sim.nodes.plant_node import PlantNode

pytestmark = pytest.mark.nodes
PARAMS = {"axes": ["x", "y"], "sample_time_s": 0.01, "duration_s": 1.0, "expected_subscribers": 1,
          "command_timeout_s": 30.0}


def command(axis: str, stamp_ns: int, value: float) -> AxisCommand:
    msg = AxisCommand(axis_name=axis, command=value, command_unit="dac")
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


def test_plant_node_steps_once_all_commands_of_a_tick_are_in_and_never_applies_nan() -> None:
    with TopicProbe({"/cnc/joint_states": JointState, "/diagnostics": DiagnosticArray}) as probe:
        pubs = {a: probe.publisher(AxisCommand, f"/cnc/servo/{a}/command") for a in ("x", "y")}
        with InProcessNode(PlantNode, PARAMS) as plant:
            probe.wait_for(lambda: len(probe.received("/cnc/joint_states")) == 1, 20.0, "tick 0")
            pubs["x"].publish(command("x", 0, 60.0))
            probe.wait_for(lambda: plant.node.matcher.pending_count == 1 and plant.node.clock.tick == 0, 5.0, "x held")
            pubs["y"].publish(command("y", 0, -60.0))
            probe.wait_for(lambda: len(probe.received("/cnc/joint_states")) == 2, 10.0, "tick 1")
            before = plant.node.plant.positions_m().copy()
            pubs["x"].publish(command("x", 10_000_000, math.nan))
            pubs["y"].publish(command("y", 10_000_000, 0.0))
            probe.wait_for(lambda: probe.received("/diagnostics"), 10.0, "the fault")
            assert plant.node.finished
            np.testing.assert_array_equal(plant.node.plant.positions_m(), before)
    ticks = probe.received("/cnc/joint_states")
    assert len(ticks) == 2, "no tick after the bad command"
    assert ticks[1].position[0] > 0.0 > ticks[1].position[1], "commands reached the right axes"
    status = probe.received("/diagnostics")[0].status[0]
    assert status.level == DiagnosticStatus.ERROR and "servo/x/command" in status.message


@pytest.mark.parametrize(("model", "section"), [("paper000", "variation"), ("paper001", "mass_friction"),
                                                ("paper003", "velocity_loop")])
def test_plant_node_declares_its_models_section_only(model: str, section: str) -> None:
    with InProcessNode(PlantNode, {**PARAMS, "model": model}) as plant:
        names = set(plant.node.get_parameters_by_prefix(""))
    sections = {name.split(".")[0] for name in names} & set(MODEL_SECTIONS)
    assert sections == {section}
    assert {f"{section}.{spec.name}" for spec in flat_specs(PLANTS[model].options)} <= names


def test_plant_node_refuses_another_models_section_naming_the_parameter_and_the_model() -> None:
    with pytest.raises(ConfigError) as err:
        InProcessNode(PlantNode, {**PARAMS, "model": "paper001", "velocity_loop.spindle_rpm": 3000.0})
    assert str(err.value).startswith("velocity_loop.spindle_rpm: a section of plant model(s) ['paper002', "
                                     "'paper003'], not of model 'paper001'"), str(err.value)
