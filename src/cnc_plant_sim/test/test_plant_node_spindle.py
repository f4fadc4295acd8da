"""Tier 2: the plant's live ``spindle_rpm`` with a real node: the periodic load follows it from the plant's
present time on; f_d at or above Nyquist is refused on /diagnostics and the schedule stays."""
from __future__ import annotations

from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from cnc_contour_control.testing import WAIT_FLOOR_S, InProcessNode, TopicProbe
from cnc_plant_sim.nodes.plant_node import PlantNode

pytestmark = pytest.mark.nodes
PARAMS = {"axes": ["x", "y"], "sample_time_s": 0.01, "duration_s": 1.0, "expected_subscribers": 1,
          "command_timeout_s": 30.0, "periodic_load.amplitude": 10.0, "periodic_load.spindle_rpm": 150.0,
          "periodic_load.flutes": 2}


def _set(probe: TopicProbe, client: AsyncParameterClient, parameter: Parameter) -> Any:
    future = client.set_parameters([parameter])
    probe.wait_for(future.done, 10.0, f"the answer to setting {parameter.name}")
    return future.result().results[0]


def test_a_live_spindle_rpm_moves_the_periodic_load_and_one_at_nyquist_is_refused_on_diagnostics() -> None:
    with TopicProbe({"/diagnostics": DiagnosticArray}) as probe, InProcessNode(PlantNode, PARAMS) as plant:
        client = AsyncParameterClient(probe.node, "/cnc/plant")
        assert client.wait_for_services(WAIT_FLOOR_S)
        load = plant.node.plant
        assert load.schedule.frequencies_hz == (5.0,)
        assert _set(probe, client, Parameter("spindle_rpm", value=450.0)).successful
        assert load.schedule.frequencies_hz[-1] == pytest.approx(15.0)
        before = load.schedule
        refused = _set(probe, client, Parameter("spindle_rpm", value=1500.0))  # f_d 50 Hz = Nyquist at 10 ms
        assert not refused.successful and "spindle_rpm" in refused.reason and "1500" in refused.reason
        assert load.schedule is before
        probe.wait_for(lambda: any(s.level == DiagnosticStatus.WARN for a in probe.received("/diagnostics")
                                   for s in a.status), 10.0, "the refusal on /diagnostics")
