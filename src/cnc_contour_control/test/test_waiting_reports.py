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


def _stamp_ns(array: DiagnosticArray) -> int:
    return int(array.header.stamp.sec) * 1_000_000_000 + int(array.header.stamp.nanosec)


def _statuses(probe: TopicProbe, level: bytes) -> list[tuple[int, DiagnosticStatus]]:
    return [(_stamp_ns(a), s) for a in probe.received("/diagnostics") for s in a.status if s.level == level]


@pytest.mark.nodes
def test_waiting_and_fault_statuses_are_stamped_in_the_runs_time_not_the_wall_clock() -> None:
    """Before its first tick a status is stamped 0; a fault after ticks 0..4 at tick 4's stamp (40 ms), as the
    run's messages are (before, both carried the wall clock: decades, mixed with a run's seconds)."""
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Header

    from cnc_contour_control.nodes.common import ns_to_stamp
    from cnc_contour_interfaces.msg import AxisCommand, Reference

    params = {**SERVO_PARAMS, "input_timeout_s": 1.0, "startup_timeout_s": 1.0}
    command = f"{NS}/servo/x/command"
    with TopicProbe({"/diagnostics": DiagnosticArray, command: AxisCommand}) as probe, \
            InProcessNode(ServoNode, params, namespace=NS) as servo:
        probe.wait_for(lambda: _statuses(probe, DiagnosticStatus.STALE), 15.0, "a STALE status of the lone servo")
        assert {stamp for stamp, _ in _statuses(probe, DiagnosticStatus.STALE)} == {0}, "no tick yet: t = 0"
        pubs = {t: probe.publisher(m, f"{NS}/{t}") for t, m in (("joint_states", JointState), ("reference", Reference))}
        probe.wait_for(lambda: all(p.get_subscription_count() for p in pubs.values()), 10.0, "the servo's inputs")
        for k in range(6):
            header = Header(stamp=ns_to_stamp(k * 10_000_000), frame_id="machine")
            pubs["reference"].publish(Reference(header=header, axis_names=["x", "y"], position_m=[0.0, 0.0],
                                                velocity_m_s=[0.0, 0.0], acceleration_m_s2=[0.0, 0.0]))
            if k < 5:  # tick 5 never gets its joint state: the servo faults waiting for it
                pubs["joint_states"].publish(JointState(header=header, name=["x", "y"], position=[0.0, 0.0],
                                                        velocity=[0.0, 0.0]))
                probe.wait_for(lambda k=k: len(probe.received(command)) == k + 1, 10.0, f"command {k}")
        probe.wait_for(lambda: _statuses(probe, DiagnosticStatus.ERROR), 15.0, "the servo's fault")
    (stamp, fault), = _statuses(probe, DiagnosticStatus.ERROR)
    assert "joint_states" in fault.message and servo.node.fault_message == fault.message
    assert stamp == 40_000_000, f"the fault is stamped at the last tick the servo took in, got {stamp} ns"
