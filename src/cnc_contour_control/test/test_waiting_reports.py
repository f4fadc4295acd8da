"""Tier 2: a node started without its partners says what it waits for (log and STALE), and STALE is no fault."""
from __future__ import annotations

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

from cnc_contour_control.core.lockstep import StampMatcher
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_contour_control.testing import InProcessNode, TopicProbe

NS = "/waiting_test"
SERVO_PARAMS = {"axis": "x", "sample_time_s": 0.01, "law": "pid", "input_timeout_s": 30.0}


def _stale(probe: TopicProbe) -> list[DiagnosticStatus]:
    return [s for a in probe.received("/diagnostics") for s in a.status if s.level == DiagnosticStatus.STALE]


@pytest.mark.nodes
def test_a_servo_alone_reports_stale_naming_each_input_and_its_publisher_count() -> None:
    with TopicProbe({"/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(ServoNode, SERVO_PARAMS, namespace=NS) as servo:
        probe.wait_for(lambda: _stale(probe), 15.0, "a STALE status of the lone servo")
    message = _stale(probe)[0].message
    assert message == (f"waiting for {NS}/joint_states: 0 of 1 publishers; {NS}/reference: 0 of 1 publishers; "
                       f"readers of {NS}/servo/x/command: 1 of 1 readers unmatched"), message
    assert servo.node.fault_message is None, "waiting is no fault"


def test_the_matcher_names_what_a_tick_waits_for_only_once_it_has_waited() -> None:
    matcher = StampMatcher(("joint_states", "reference"), 5.0)
    assert matcher.waiting_for(0.0, 1.0) == ["joint_states", "reference"], "before any input: every one"
    matcher.add("joint_states", 0, "js", now_s=10.0)
    assert matcher.waiting_for(10.5, 1.0) == [], "pending for 0.5 s: not yet"
    assert matcher.waiting_for(11.5, 1.0) == ["reference"]
    assert matcher.add("reference", 0, "ref", now_s=11.6) is not None
    assert matcher.waiting_for(100.0, 1.0) == [], "between ticks the pace is the ticker's"
