"""Tier 1: a lockstep input's publishers leaving is a lost partner, named with the topic (no ROS)."""
from __future__ import annotations

from cnc_contour_control.axis.safety import EstopLatch, PartnerWatch

TOPIC = "/cnc/r1/servo/x/command"


def test_publishers_that_all_leave_are_named_with_the_topic_and_the_stamp() -> None:
    watch = PartnerWatch([TOPIC])
    assert watch.observe(TOPIC, [], 0) is None, "never had one: not a loss (start-up)"
    assert watch.observe(TOPIC, ["/cnc/r1/servo_x"], 10_000_000) is None
    assert watch.observe(TOPIC, [], 1_220_000_000) is None, "one empty look may be a starved graph query"
    lost = watch.observe(TOPIC, [], 1_230_000_000)
    assert lost is not None
    assert "/cnc/r1/servo_x left the graph" in lost and TOPIC in lost and "t=1.230000 s" in lost
    assert watch.publishers(TOPIC) == ("/cnc/r1/servo_x",)


def test_one_of_two_publishers_leaving_is_no_loss() -> None:
    watch = PartnerWatch([TOPIC])
    watch.observe(TOPIC, ["/a", "/b"], 0)
    assert watch.observe(TOPIC, ["/b"], 1) is None
    watch.observe(TOPIC, [], 2)
    assert "/b left" in (watch.observe(TOPIC, [], 3) or "")


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
    watch.observe(TOPIC, [], 3)
    assert "/cnc/r1/servo_x left" in (watch.observe(TOPIC, [], 4) or "")


def test_a_publisher_seen_again_between_two_empty_looks_is_no_loss() -> None:
    watch = PartnerWatch([TOPIC], confirm=2)
    watch.observe(TOPIC, ["/a"], 0)
    for k in range(1, 20):
        assert watch.observe(TOPIC, [] if k % 2 else ["/a"], k) is None, "never two empty looks in a row"
