"""Tier 2: the plant node with a cutting process publishes cutting_force every tick, as the core plant computes it."""
from __future__ import annotations

import pytest
from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import JointState

from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import AxisCommand
from cnc_plant_sim.models.plant import make_plant
from cnc_plant_sim.nodes.plant_node import PlantNode
from cnc_plant_sim.process.cutting import cutting_force_n

pytestmark = pytest.mark.nodes
NS = "/cutting_plant_test"
CUTTING = {"cutting.process": "turning", "cutting.feed_axis": "z", "cutting.depth_schedule_t_s": [0.0, 0.02],
           "cutting.depth_schedule_mm": [1.0, 2.0], "cutting.turning.spindle_rpm": 600.0}
PARAMS = {"model": "paper003", "axes": ["x", "z"], "velocity_loop.spindle_rpm": 0.0, "sample_time_s": 0.01,
          "duration_s": 1.0, "expected_subscribers": 1, "cutting_force_subscribers": 1, "command_timeout_s": 30.0,
          **CUTTING}
COMMANDS_M_S = (0.002, 0.002, 0.001, 0.0)


def command(axis: str, stamp_ns: int, value: float) -> AxisCommand:
    msg = AxisCommand(axis_name=axis, command=value, command_unit="m/s")
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


def test_the_plant_node_publishes_the_core_plants_cutting_force_in_the_tool_frame() -> None:
    topics = {f"{NS}/joint_states": JointState, f"{NS}/cutting_force": WrenchStamped}
    with TopicProbe(topics) as probe, InProcessNode(PlantNode, PARAMS, namespace=NS) as plant:
        pubs = {a: probe.publisher(AxisCommand, f"{NS}/servo/{a}/command") for a in ("x", "z")}
        for k, value in enumerate(COMMANDS_M_S):
            probe.wait_for(lambda k=k: len(probe.received(f"{NS}/cutting_force")) == k + 1, 20.0, f"tick {k}")
            pubs["x"].publish(command("x", k * 10_000_000, 0.0))
            pubs["z"].publish(command("z", k * 10_000_000, value))
        probe.wait_for(lambda: len(probe.received(f"{NS}/cutting_force")) == len(COMMANDS_M_S) + 1, 10.0, "the last")
        described = {d.name: d for d in plant.node.describe_parameters(list(CUTTING))}
    core = make_plant({"model": "paper003", "axes": ["x", "z"], "velocity_loop": {"spindle_rpm": 0.0},
                       "cutting": {"process": "turning", "feed_axis": "z",
                                   "depth_schedule": [[0.0, 1.0], [0.02, 2.0]]}})
    core.reset([0.0, 0.0])
    expected = [cutting_force_n(core)]
    for value in COMMANDS_M_S:
        core.step([0.0, value], 0.01)
        expected.append(cutting_force_n(core))
    got = probe.received(f"{NS}/cutting_force")
    assert [m.wrench.force.x for m in got] == expected and max(expected) > 0.0
    assert all(m.header.frame_id == "tool" and m.wrench.force.y == m.wrench.force.z == 0.0 for m in got)
    assert [m.header.stamp.nanosec for m in got] == [k * 10_000_000 for k in range(len(expected))]
    assert "[mm]" in described["cutting.depth_schedule_mm"].description and described["cutting.process"].read_only
    assert described["cutting.turning.spindle_rpm"].floating_point_range[0].to_value == 1.0e5
