"""Tier 2: the force-regulator node in-process with real rclpy and DDS (loopback), real messages."""
from __future__ import annotations

import math

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped

from cnc_contour_control.force import ForceRegulator, ForceRegulatorConfig, QuantiserConfig
from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.nodes.force_regulator_node import ForceRegulatorNode
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import FeedOverride

pytestmark = pytest.mark.nodes
NS = "/force_node_test"
PARAMS = {"sample_time_s": 0.01, "reference_n": 500.0, "law": "pi", "update_period_s": 0.01,
          "quantiser.step_ratio": 0.1, "stale_timeout_s": 0.3, "input_timeout_s": 30.0}
PROBE = {f"{NS}/feed_override": FeedOverride, "/diagnostics": DiagnosticArray}


def wrench(stamp_ns: int, force_n: float) -> WrenchStamped:
    msg = WrenchStamped()
    msg.header.stamp, msg.header.frame_id = ns_to_stamp(stamp_ns), "tool"
    msg.wrench.force.x = force_n
    return msg


def statuses(probe: TopicProbe, level: bytes) -> list[DiagnosticStatus]:
    return [s for a in probe.received("/diagnostics") for s in a.status if s.level == level]


def _ready(probe: TopicProbe) -> object:
    forces = probe.publisher(WrenchStamped, f"{NS}/cutting_force")
    probe.wait_for(lambda: forces.get_subscription_count() > 0, 15.0, "the regulator's subscription")
    return forces


def test_the_node_publishes_what_the_core_regulator_gives_stamped_with_the_force() -> None:
    forces_n = (0.0, 120.0, 380.0, 510.0, 640.0, 470.0)
    with TopicProbe(PROBE) as probe, InProcessNode(ForceRegulatorNode, PARAMS, namespace=NS):
        forces = _ready(probe)
        for k, force_n in enumerate(forces_n):
            forces.publish(wrench(k * 10_000_000, force_n))
        probe.wait_for(lambda: len(probe.received(f"{NS}/feed_override")) == len(forces_n), 10.0, "every override")
    core = ForceRegulator(ForceRegulatorConfig(law="pi", quantiser=QuantiserConfig(step_ratio=0.1)))
    for k, (force_n, msg) in enumerate(zip(forces_n, probe.received(f"{NS}/feed_override"))):
        expected = core.step(0.01, force_n, 500.0)
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (0, k * 10_000_000)
        assert (msg.requested_ratio, msg.applied_ratio, msg.quantum) == (expected.requested_ratio,
                                                                        expected.applied_ratio, 0.1)
    assert len({m.applied_ratio for m in probe.received(f"{NS}/feed_override")}) > 1, "the override moved"


def test_a_non_finite_force_is_a_fault_naming_the_field_and_the_value() -> None:
    with TopicProbe(PROBE) as probe, InProcessNode(ForceRegulatorNode, PARAMS, namespace=NS) as node:
        forces = _ready(probe)
        forces.publish(wrench(0, math.nan))
        probe.wait_for(lambda: statuses(probe, DiagnosticStatus.ERROR), 10.0, "the fault")
    message = statuses(probe, DiagnosticStatus.ERROR)[0].message
    assert "cutting_force.wrench.force.x" in message and "nan" in message
    assert node.node.fault_message == message
    assert probe.received(f"{NS}/feed_override") == [], "nothing published on a bad force"


def test_a_force_that_stops_is_reported_stale_and_the_last_override_holds() -> None:
    with TopicProbe(PROBE) as probe, InProcessNode(ForceRegulatorNode, PARAMS, namespace=NS) as node:
        forces = _ready(probe)
        for k in range(3):
            forces.publish(wrench(k * 10_000_000, 900.0))
        probe.wait_for(lambda: statuses(probe, DiagnosticStatus.STALE), 10.0, "the STALE status")
        held = probe.received(f"{NS}/feed_override")
        forces.publish(wrench(30_000_000, 900.0))
        probe.wait_for(lambda: statuses(probe, DiagnosticStatus.OK), 10.0, "the force back")
    stale = statuses(probe, DiagnosticStatus.STALE)[0]
    values = {kv.key: kv.value for kv in stale.values}
    assert len(held) == 3 and float(values["applied_ratio"]) == held[-1].applied_ratio
    assert "stale_timeout_s 0.3" in stale.message and f"{NS}/cutting_force" in stale.message
    assert node.node.fault_message is None, "a stale force is no fault"
    assert len(probe.received(f"{NS}/feed_override")) == 4, "the loop goes on when the force is back"
