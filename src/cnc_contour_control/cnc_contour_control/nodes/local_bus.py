"""A process-local bus: messages between nodes of one process handed over as Python objects (composed mode).

What rclcpp's intra-process communication does, in Python. A composed host
(``cnc_tools.nodes.composed_host``) attaches a :class:`LocalBus` to its
context; every :class:`~cnc_contour_control.nodes.common.SuiteNode` built on
that context then creates its publishers and subscriptions through the bus:

* a **publication** is queued for every subscription of a member on the same
  resolved topic and type (one FIFO queue, drained by the host's spin loop:
  no callback calls another, so the lockstep order and the stack depth are
  those of an executor), and goes to DDS only when a DDS reader is matched
  (a reader outside the process: the recorder, a user's tool) or the topic is
  latched (late joiners need DDS's history);
* a **subscription** of a member is served by the bus alone while every
  publisher of its topic in the ROS graph is a member; once the graph shows
  a publisher outside the process (a user's ``feed_override`` or e-stop, a
  replay, an injected fault), the host's poll (:meth:`LocalBus.connect_outside`)
  gives it a DDS subscription and, once the member publishers matched it,
  takes it off the bus, so it gets every message once: the outside ones and
  the members' over DDS. (Jazzy's rclpy gives no publisher gid with a
  message, so echoes cannot be filtered at the reader.)
* latched (transient-local) endpoints always use DDS.

Separate processes never attach a bus: their nodes use rclpy unchanged.
"""
from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.serialization import serialize_message

from cnc_contour_control.nodes import fast_cdr

#: Buses by the context their members share (one per composed process).
_BUSES: dict[int, LocalBus] = {}
#: Deliveries the host makes per turn before it lets the executor run timers and DDS events.
DRAIN_BATCH = 64


def attach(context: Any, bus: LocalBus) -> None:
    """Serve every SuiteNode built on ``context`` from now on through ``bus``."""
    _BUSES[id(context)] = bus


def detach(context: Any) -> None:
    """Stop serving nodes of ``context`` (nodes already built keep their endpoints)."""
    _BUSES.pop(id(context), None)


def bus_of(context: Any) -> LocalBus | None:
    """The bus attached to ``context``, or None (a separate process: plain rclpy)."""
    return _BUSES.get(id(context))


def is_latched(qos: QoSProfile | int) -> bool:
    """True for a transient-local profile (an int is a depth: volatile)."""
    return isinstance(qos, QoSProfile) and qos.durability == DurabilityPolicy.TRANSIENT_LOCAL


def node_name(node: Any) -> str:
    """``/ns/name`` of a node."""
    return str(node.get_fully_qualified_name())


@dataclass(eq=False)
class LocalSubscription:
    """A member's subscription: served by the bus until it has a DDS subscription of its own."""

    node: Any
    topic: str
    msg_type: type
    callback: Callable[[Any], Any]
    qos: QoSProfile | int
    raw: bool
    options: dict[str, Any] = field(default_factory=dict)
    dds: Any = None
    active: bool = True

    @property
    def local(self) -> bool:
        """True while the bus delivers to it (no DDS subscription yet)."""
        return self.active and self.dds is None

    def __post_init__(self) -> None:
        self.encode = (fast_cdr.encoder(self.msg_type) or serialize_message) if self.raw else None

    def deliver(self, msg: Any) -> None:
        """Call the member's callback (serialized CDR for a raw subscription, as DDS would give it)."""
        if self.active:
            self.callback(self.encode(msg) if self.encode is not None else msg)


class BusPublisher:
    """A member's publisher: queues each message for the member subscriptions, and publishes to DDS if read there.

    Everything else (``topic_name``, ``qos_profile``, ``wait_for_all_acked``...)
    is the rclpy publisher's.
    """

    def __init__(self, bus: LocalBus, node: Any, publisher: Any, msg_type: type) -> None:
        self.bus, self.node, self.publisher, self.msg_type = bus, node, publisher, msg_type
        self.topic = publisher.topic_name
        self.dds = fast_cdr.fast_publisher(publisher, msg_type)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.publisher, name)

    def publish(self, msg: Any) -> None:
        """Queue ``msg`` for the member subscriptions; to DDS when a DDS reader is matched."""
        self.bus.enqueue(self.topic, self.msg_type, msg)
        if self.publisher.get_subscription_count() > 0:
            self.dds.publish(msg)

    def local_readers(self) -> list[str]:
        """Node names of the member subscriptions the bus serves on this topic (the DDS graph does not show them)."""
        return [node_name(s.node) for s in self.bus.subscriptions_of(self.topic, self.msg_type) if s.local]

    def get_subscription_count(self) -> int:
        """Matched DDS readers plus the member subscriptions the bus serves."""
        return int(self.publisher.get_subscription_count()) + len(self.local_readers())


class LocalBus:
    """Member endpoints by topic, and the queue of deliveries the host drains."""

    def __init__(self) -> None:
        self.queue: deque[tuple[LocalSubscription, Any]] = deque()
        self.subscriptions: dict[str, list[LocalSubscription]] = {}
        self.publishers: dict[str, list[BusPublisher]] = {}
        self.delivered = 0
        self.connected: list[str] = []  # topics whose member subscriptions moved to DDS (an outside publisher)
        self.former: set[str] = set()  # members that ended: the graph may show their endpoints a while longer

    def publisher(self, node: Any, publisher: Any, msg_type: type) -> BusPublisher:
        """Wrap a member's rclpy publisher (already created, so the graph and DDS readers see it)."""
        wrapped = BusPublisher(self, node, publisher, msg_type)
        self.publishers.setdefault(wrapped.topic, []).append(wrapped)
        return wrapped

    def subscribe(self, subscription: LocalSubscription) -> LocalSubscription:
        """Serve a member's subscription from the bus (the host's poll connects it to outside publishers)."""
        self.subscriptions.setdefault(subscription.topic, []).append(subscription)
        return subscription

    def subscriptions_of(self, topic: str, msg_type: type) -> list[LocalSubscription]:
        """The member subscriptions of ``topic`` with ``msg_type``."""
        return [s for s in self.subscriptions.get(topic, ()) if s.msg_type is msg_type]

    def enqueue(self, topic: str, msg_type: type, msg: Any) -> None:
        """Queue ``msg`` once for every subscription the bus serves on ``topic``."""
        for subscription in self.subscriptions.get(topic, ()):
            if subscription.dds is None and subscription.msg_type is msg_type:
                self.queue.append((subscription, msg))

    @property
    def pending(self) -> bool:
        """True while deliveries are queued."""
        return bool(self.queue)

    def drain(self, limit: int = DRAIN_BATCH) -> int:
        """Make up to ``limit`` deliveries in publication order (a callback's publications queue behind); the count."""
        done = 0
        while self.queue and done < limit:
            subscription, msg = self.queue.popleft()
            done += 1
            subscription.deliver(msg)
        self.delivered += done
        return done

    def forget(self, node: Any) -> None:
        """Drop a member's endpoints (it ended): nothing more is delivered to it."""
        self.former.add(node_name(node))
        for subscriptions in self.subscriptions.values():
            for subscription in [s for s in subscriptions if s.node is node]:
                subscription.active = False
                subscriptions.remove(subscription)
        for publishers in self.publishers.values():
            publishers[:] = [p for p in publishers if p.node is not node]

    def members(self) -> set[str]:
        """Node names of every member with an endpoint on the bus, and of those that ended."""
        nodes = [s.node for subs in self.subscriptions.values() for s in subs]
        nodes += [p.node for pubs in self.publishers.values() for p in pubs]
        return {node_name(n) for n in nodes} | self.former

    def connect_outside(self, wait_s: float = 2.0) -> list[str]:
        """Give a DDS subscription to every bus-served subscription whose topic has a publisher outside the process.

        Called by the host between deliveries (no member publishes meanwhile):
        the subscription leaves the bus only once every member publisher of
        the topic matched it, so no message is lost or delivered twice. The
        topics connected.
        """
        members, connected = self.members(), []
        for topic, subscriptions in self.subscriptions.items():
            waiting = [s for s in subscriptions if s.local]
            if waiting and _outside_publisher(waiting[0].node, topic, members):
                connected += [topic] * sum(self._connect(s, wait_s) for s in waiting)
        self.connected += connected
        return connected

    def _connect(self, subscription: LocalSubscription, wait_s: float) -> bool:
        """Create the DDS subscription; leave the bus once the member publishers matched it (else undo)."""
        node = subscription.node
        publishers = [p for p in self.publishers.get(subscription.topic, ()) if p.msg_type is subscription.msg_type]
        before = [p.publisher.get_subscription_count() for p in publishers]
        dds = node.create_dds_subscription(subscription.msg_type, subscription.topic, subscription.callback,
                                           subscription.qos, raw=subscription.raw, **subscription.options)
        if _wait_matched(dds, publishers, before, wait_s):
            subscription.dds = dds
            return True
        node.destroy_subscription(dds)
        return False


def _outside_publisher(node: Any, topic: str, members: set[str]) -> bool:
    """True if the graph shows a publisher of ``topic`` on a node that is not a member."""
    infos = node.get_publishers_info_by_topic(topic)
    return any(f"{i.node_namespace.rstrip('/')}/{i.node_name}" not in members for i in infos)


def _wait_matched(dds: Any, publishers: list[BusPublisher], before: list[int], wait_s: float) -> bool:
    """Wait (bounded) until the subscription matched every member publisher and each of them matched one more reader.

    Matching happens on DDS's own threads; rclpy offers no event for it
    without spinning the executor, which must not run here, so the counts are
    polled every 5 ms.
    """
    deadline = time.monotonic() + wait_s
    while True:
        counts = [p.publisher.get_subscription_count() for p in publishers]
        if dds.get_publisher_count() >= len(publishers) and all(n > b for n, b in zip(counts, before)):
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.005)


def local_readers(publisher: Any) -> list[str]:
    """Node names of the member subscriptions a bus serves for ``publisher`` (none for a plain rclpy publisher)."""
    return publisher.local_readers() if isinstance(publisher, BusPublisher) else []
