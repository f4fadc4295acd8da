"""Tier 2: the servo's live ``spindle_rpm`` with a real node: the PDC redesigns; a speed it cannot follow is
refused on /diagnostics and the last valid design stays (issue 10, Bad input)."""
from __future__ import annotations

from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from cnc_contour_control.laws import law_config
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_contour_control.testing import WAIT_FLOOR_S, InProcessNode, TopicProbe

pytestmark = pytest.mark.nodes
PARAMS = {"axis": "x", "sample_time_s": 0.001, "law": "pdc", "input_timeout_s": 30.0, "gains.spindle_rpm": 1500.0}


def _set(probe: TopicProbe, client: AsyncParameterClient, parameter: Parameter) -> Any:
    """Set one parameter through the node's parameter service (as ``ros2 param set`` does)."""
    future = client.set_parameters([parameter])
    probe.wait_for(future.done, 10.0, f"the answer to setting {parameter.name}")
    return future.result().results[0]


def _warnings(probe: TopicProbe) -> list[DiagnosticStatus]:
    return [s for a in probe.received("/diagnostics") for s in a.status if s.level == DiagnosticStatus.WARN]


def test_a_live_spindle_rpm_redesigns_the_pdc_and_one_it_cannot_follow_is_refused_on_diagnostics() -> None:
    with TopicProbe({"/diagnostics": DiagnosticArray}) as probe, InProcessNode(ServoNode, PARAMS) as servo:
        client = AsyncParameterClient(probe.node, "/cnc/servo")
        assert client.wait_for_services(WAIT_FLOOR_S)
        law = servo.node.controller.law
        assert law.design.f_d_hz == pytest.approx(50.0)
        assert _set(probe, client, Parameter("spindle_rpm", value=1800.0)).successful
        assert law.design.h == law_config("pdc", {"spindle_rpm": 1800.0}).pdc_design().h  # redesigned for 60 Hz
        refused = _set(probe, client, Parameter("spindle_rpm", value=20000.0))
        assert not refused.successful
        assert "spindle_rpm" in refused.reason and "9000" in refused.reason and "20000" in refused.reason
        assert law.design.f_d_hz == pytest.approx(60.0), "the last valid design stays"
        probe.wait_for(lambda: _warnings(probe), 10.0, "the refusal on /diagnostics")
        assert "servo x" in _warnings(probe)[0].message and "20000" in _warnings(probe)[0].message
        assert _set(probe, client, Parameter("spindle_rpm", value=1650)).successful  # an integer, as ros2 param set
        assert _set(probe, client, Parameter("gains.kp", value=35.0)).successful
        assert law.config.kp == 35.0 and law.design.f_d_hz == pytest.approx(55.0), "the live speed outlives a retune"
