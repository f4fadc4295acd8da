"""Tier 1: a lockstep input's publishers leaving is a lost partner, named with the topic (no ROS)."""
from __future__ import annotations

from cnc_contour_control.axis.safety import EstopLatch, PartnerWatch

TOPIC = "/cnc/r1/servo/x/command"


def test_publishers_that_all_leave_are_named_with_the_topic_and_the_stamp() -> None:
    watch = PartnerWatch([TOPIC])
    assert watch.observe(TOPIC, [], 0) is None, "never had one: not a loss (start-up)"
    assert watch.observe(TOPIC, ["/cnc/r1/servo_x"], 10_000_000) is None
    lost = watch.observe(TOPIC, [], 1_230_000_000)
    assert lost is not None
    assert "/cnc/r1/servo_x left the graph" in lost and TOPIC in lost and "t=1.230000 s" in lost
    assert watch.publishers(TOPIC) == ("/cnc/r1/servo_x",)


def test_one_of_two_publishers_leaving_is_no_loss() -> None:
    watch = PartnerWatch([TOPIC])
    watch.observe(TOPIC, ["/a", "/b"], 0)
    assert watch.observe(TOPIC, ["/b"], 1) is None
    assert "/b left" in (watch.observe(TOPIC, [], 2) or "")


def test_a_trip_latches_without_the_estop_input_and_reset_clears_it() -> None:
    latch = EstopLatch()
    assert latch.trip("servo_x left") and not latch.trip("again")
    assert latch.latched and not latch.estop_input and latch.gate([3.0]) == [0.0]
    assert not latch.enable(True).accepted
    assert latch.reset().accepted and latch.enable(True).accepted and latch.gate([3.0]) == [3.0]


def test_an_endpoint_not_yet_named_keeps_the_known_name() -> None:
    watch = PartnerWatch([TOPIC])
    watch.observe(TOPIC, [None], 0)
    assert watch.publishers(TOPIC) == ("an unnamed node",)
    watch.observe(TOPIC, ["/cnc/r1/servo_x"], 1)
    watch.observe(TOPIC, [None], 2)
    assert "/cnc/r1/servo_x left" in (watch.observe(TOPIC, [], 3) or "")
