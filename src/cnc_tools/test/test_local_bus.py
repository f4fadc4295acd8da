"""The composed host's local bus: members talk in process; an outside publisher still reaches them, nothing twice."""
from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import rclpy
from rclpy.context import Context
from std_msgs.msg import String

from cnc_contour_control.nodes import local_bus
from cnc_contour_control.nodes.common import SuiteNode
from cnc_tools.nodes.composed_host import ComposedHost

pytestmark = pytest.mark.nodes  # a composed host and an outside node: real participants

NAMESPACE = "/local_bus_test"
TOPIC = f"{NAMESPACE}/chatter"


class _Talker(SuiteNode):
    """Publishes ``local <i>`` every 2 ms through a gated publisher that waits for the listener."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("talker", **kwargs)
        self.sent = 0
        self.running = True
        self.pub = self.gated_publisher(String, "chatter", 1)
        self.create_timer(0.002, self._tick)

    def _tick(self) -> None:
        if self.running and self.pub.is_open:
            self.pub.publish(String(data=f"local {self.sent}"))
            self.sent += 1


class _Listener(SuiteNode):
    """Keeps every message it gets."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("listener", **kwargs)
        self.got: list[str] = []
        self.create_subscription(String, "chatter", lambda msg: self.got.append(msg.data), 100)


def _args(name: str, *extra: str) -> list[str]:
    return ["--ros-args", "-r", f"__ns:={NAMESPACE}", "-r", f"__node:={name}", *extra]


@pytest.fixture
def host(tmp_path: Path) -> Iterator[ComposedHost]:
    context = Context()
    rclpy.init(context=context)
    composed = ComposedHost(context, tmp_path / "exits.json")
    try:
        yield composed
    finally:
        composed.close()
        rclpy.try_shutdown(context=context)


def _spin_until(host: ComposedHost, condition: Callable[[], bool], what: str, timeout_s: float = 20.0) -> None:
    deadline = time.monotonic() + timeout_s
    host.spin(until=lambda: condition() or time.monotonic() > deadline)
    assert condition(), f"not within {timeout_s} s: {what}"


def test_members_talk_in_process_and_an_outside_publisher_reaches_them_once(host: ComposedHost) -> None:
    assert host.bus is not None, "the composed host serves its members through a local bus by default"
    host.add("talker", _Talker, _args("talker", "-p", "required_readers:=[listener]"))
    host.add("listener", _Listener, _args("listener"))
    talker, listener = host.live["talker"], host.live["listener"]
    _spin_until(host, lambda: len(listener.got) >= 20, "20 local messages")
    subscription = host.bus.subscriptions_of(TOPIC, String)[0]
    assert subscription.dds is None and talker.pub.publisher.publisher.get_subscription_count() == 0, \
        "only members: served by the bus, nothing over DDS"
    gate = talker.pub.gate
    assert talker.pub.is_open and gate is not None and gate.required == (f"{NAMESPACE}/listener",), \
        "the gate counts the listener the bus serves"
    assert host.bus.delivered >= 20

    outside_context = Context()
    rclpy.init(context=outside_context)
    try:
        outside = rclpy.create_node("outside", namespace=NAMESPACE, context=outside_context)
        publisher = outside.create_publisher(String, "chatter", 100)
        _spin_until(host, lambda: subscription.dds is not None and publisher.get_subscription_count() >= 1,
                    "the listener connected to the outside publisher")
        for j in range(10):
            publisher.publish(String(data=f"outside {j}"))
        _spin_until(host, lambda: sum(m.startswith("outside") for m in listener.got) >= 10, "10 outside messages")
        talker.running = False
        sent = talker.sent
        _spin_until(host, lambda: sum(m.startswith("local") for m in listener.got) >= sent, "every local message")
    finally:
        rclpy.try_shutdown(context=outside_context)
    counts = Counter(listener.got)
    assert max(counts.values()) == 1, f"delivered twice: {[m for m, n in counts.items() if n > 1]}"
    local = [int(m.split()[1]) for m in listener.got if m.startswith("local")]
    assert local == list(range(sent)), "every local message once, in order, across the move to DDS"
    assert sorted(m for m in counts if m.startswith("outside")) == sorted(f"outside {j}" for j in range(10))
    assert host.bus.connected == [TOPIC]


def test_without_the_bus_members_use_dds(host: ComposedHost) -> None:
    local_bus.detach(host.context)
    host.bus = None
    host.add("talker", _Talker, _args("talker", "-p", "required_readers:=[listener]"))
    host.add("listener", _Listener, _args("listener"))
    talker, listener = host.live["talker"], host.live["listener"]
    _spin_until(host, lambda: len(listener.got) >= 5, "5 messages over DDS")
    assert not isinstance(talker.pub.publisher, local_bus.BusPublisher)
    assert talker.pub.publisher.get_subscription_count() == 1
