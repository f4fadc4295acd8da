"""The ``live`` node: every suite topic of its namespace to a live server, as it arrives (rclpy).

It looks at the graph every :data:`DISCOVERY_PERIOD_S` and subscribes (raw CDR, no decoding in rclpy) to each
topic of its namespace whose type the suite knows: ``path`` latched, ``diagnostics`` (the runner remaps
``/diagnostics`` into the run's namespace) as statuses, the rest lockstep. So it serves graphs started by hand,
by ``cnc-contour run --live`` (in the runner's process, :class:`LiveThread`) and replays alike. The clock is not
forwarded. ``live --ros-args -r __ns:=/cnc -p port:=8765`` (``host:=ADDRESS`` for another address, said loudly).
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from cnc_contour_control.core import topics
from cnc_contour_control.core.errors import CncError
from cnc_contour_control.nodes.common import (
    LATCHED_QOS,
    LOCKSTEP_QOS,
    SuiteNode,
    describe,
    message_class,
    spin_node,
)
from cnc_tools.live.decimate import WINDOW_NS
from cnc_tools.live.feed import LiveFeed
from cnc_tools.live.server import DEFAULT_HOST, DEFAULT_PORT, LiveConfig, LiveServer

#: Wall seconds between two looks for new topics.
DISCOVERY_PERIOD_S = 0.2
#: Wall time the viewer's request waits for the graph's answer (a parameter service, ``~/enable``), s.
ANSWER_TIMEOUT_S = 2.0
#: Wall time the live node waits to discover a node's service or a topic's readers, s (a new participant sees
#: the graph after 2-3 s on a loaded machine; a request before that waits).
DISCOVERY_TIMEOUT_S = 10.0
#: Types never forwarded (the clock: every tick twice over, nothing to see).
SKIPPED_TYPES = frozenset({topics.CLOCK.type_name})


class LiveNode(SuiteNode):
    """Subscribes to the suite's topics of its namespace and feeds them to a live server."""

    def __init__(self, feed: LiveFeed | None = None, clock: Callable[[], int] = time.time_ns, **kwargs: Any) -> None:
        super().__init__("live", **kwargs)
        self.clock = clock  # log time of a forwarded message, ns (a replay's: its timeline time)
        host = self.declare("host", DEFAULT_HOST, describe(
            "address the live server binds (anything but loopback is warned about)", read_only=True))
        port = self.declare("port", DEFAULT_PORT, describe("TCP port of the live server (0: any free)", 0, 65535,
                                                           read_only=True, integer=True))
        self.owns_server = feed is None
        if feed is None:  # a graph started by hand: the viewer publishes onto it (no scenario: no parameters)
            from cnc_tools.live.talkback import GraphTalkback

            talkback = GraphTalkback(None)
            feed = LiveFeed(LiveServer(LiveConfig(host=host, port=int(port)), **talkback.server_options()), WINDOW_NS)
            talkback.attach(feed.server)
            talkback.bus = RosBus(self)
            self.get_logger().info(f"live server on {feed.server.url}")
        self.feed = feed
        self.subscribed: set[str] = set()
        self.create_timer(DISCOVERY_PERIOD_S, self.guarded(self._discover))
        self._discover()

    def _discover(self) -> None:
        namespace = self.get_namespace()
        known = self.feed.store.types
        for name, type_names in self.get_topic_names_and_types():
            relative = topics.relative(namespace, name)
            if name in self.subscribed or relative == name or len(type_names) != 1:
                continue  # outside this namespace, or several types on one name
            type_name = type_names[0]
            if type_name in SKIPPED_TYPES or type_name not in known:
                continue
            self._subscribe(name, relative, type_name)

    def _subscribe(self, name: str, relative: str, type_name: str) -> None:
        feed_name = topics.DIAGNOSTICS.name if type_name == topics.DIAGNOSTICS.type_name else relative
        qos = LATCHED_QOS if type_name == topics.PATH.type_name else LOCKSTEP_QOS
        publish, clock = self.feed.publish, self.clock
        self.feed.advertise(feed_name, type_name)

        def forward(cdr: bytes) -> None:
            publish(feed_name, type_name, cdr, clock())

        self.create_subscription(message_class(type_name, name), name, self.guarded(forward), qos, raw=True)
        self.subscribed.add(name)

    def destroy_node(self) -> None:
        """Close the open windows; stop the server if this node started it."""
        self.feed.finish(self.clock())
        if self.owns_server:
            self.feed.server.close()
        super().destroy_node()


class RosBus:
    """The graph side of the viewer's requests (``live/talkback.py`` :class:`GraphTalkback`), on a spinning
    :class:`LiveNode`: parameter services, ``feed_override`` and ``estop`` publishers, ``~/enable`` services. Called
    from the live server's thread; each answer is waited for up to :data:`ANSWER_TIMEOUT_S`."""

    def __init__(self, node: LiveNode) -> None:
        from std_msgs.msg import Bool

        from cnc_contour_interfaces.msg import FeedOverride

        self.node, self._bool, self._override = node, Bool, FeedOverride
        self._publishers: dict[str, Any] = {}  # made on the first request: a run nobody talks to is unchanged
        self._parameters: dict[str, Any] = {}
        self._lock = threading.Lock()

    def _send(self, topic: str, message: Any) -> None:
        """``message`` on ``topic`` once the graph shows a reader and every reader matched (a new writer's first
        message is otherwise lost to a reader not matched yet); acknowledged by all, or an error naming the topic."""
        from rclpy.duration import Duration

        with self._lock:
            publisher = self._publishers.get(topic)
            if publisher is None:
                publisher = self._publishers[topic] = self.node.create_publisher(type(message), topic, 10)
        name = publisher.topic_name
        deadline = time.monotonic() + DISCOVERY_TIMEOUT_S
        while not 0 < self._readers(name) <= publisher.get_subscription_count():
            if time.monotonic() > deadline:
                raise CncError(f"no reader of {name} within {DISCOVERY_TIMEOUT_S} s (is the graph running?)")
            time.sleep(0.01)  # discovery runs in DDS's threads: nothing to wait on from here
        publisher.publish(message)
        if not publisher.wait_for_all_acked(Duration(seconds=ANSWER_TIMEOUT_S)):
            raise CncError(f"{name}: not every reader acknowledged within {ANSWER_TIMEOUT_S} s")

    def _readers(self, topic: str) -> int:
        """Readers of ``topic`` the graph shows, but the live node's own (it forwards every suite topic)."""
        me = (self.node.get_namespace(), self.node.get_name())
        return sum((info.node_namespace, info.node_name) != me
                   for info in self.node.get_subscriptions_info_by_topic(topic))

    def _answer(self, future: Any, what: str) -> Any:
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if not done.wait(ANSWER_TIMEOUT_S):
            raise CncError(f"{what}: no answer within {ANSWER_TIMEOUT_S} s")
        return future.result()

    def set_parameter(self, node: str, name: str, value: float | int | bool) -> str | None:
        """``name`` set through the parameter service of ``node`` of the namespace; its refusal's reason or None."""
        from rclpy.parameter import Parameter
        from rclpy.parameter_client import AsyncParameterClient

        target = f"{self.node.get_namespace().rstrip('/')}/{node}"
        with self._lock:
            client = self._parameters.get(target) or AsyncParameterClient(self.node, target)
            self._parameters[target] = client
        if not client.wait_for_services(DISCOVERY_TIMEOUT_S):
            return f"no parameter service of {target} within {DISCOVERY_TIMEOUT_S} s"
        result = self._answer(client.set_parameters([Parameter(name, value=value)]), f"{target} {name}").results[0]
        return None if result.successful else str(result.reason)

    def publish_override(self, ratio: float) -> None:
        """A request of ``ratio`` (applied_ratio too: the interpolator takes it as given) on ``feed_override``."""
        stamp = self.node.get_clock().now().to_msg()
        message = self._override(requested_ratio=ratio, applied_ratio=ratio, quantum=0.0)
        message.header.stamp, message.header.frame_id = stamp, "machine"
        self._send(topics.FEED_OVERRIDE.name, message)

    def publish_estop(self, value: bool) -> None:
        """``value`` on ``estop``, as ``cnc-contour machine estop|release`` sends it."""
        self._send("estop", self._bool(data=value))

    def enable(self, value: bool) -> list[str]:
        """``~/enable`` on every node of the namespace that offers it; the refusals (service: reason)."""
        from std_srvs.srv import SetBool

        prefix = self.node.get_namespace().rstrip("/") + "/"
        names = sorted(name for name, types in self.node.get_service_names_and_types()
                       if name.startswith(prefix) and name.endswith("/enable") and "std_srvs/srv/SetBool" in types
                       and name.count("/") == prefix.count("/") + 1)
        refusals = [] if names else [f"no {prefix}*/enable service in the graph"]
        for name in names:
            client = self.node.create_client(SetBool, name)
            try:
                if not client.wait_for_service(timeout_sec=DISCOVERY_TIMEOUT_S):
                    raise CncError(f"{name}: not ready within {DISCOVERY_TIMEOUT_S} s")
                answer = self._answer(client.call_async(SetBool.Request(data=value)), name)
            except CncError as err:
                refusals.append(str(err))
                continue
            finally:
                self.node.destroy_client(client)
            if not answer.success:
                refusals.append(f"{name}: {answer.message}")
        return refusals


class LiveThread:
    """A :class:`LiveNode` in a thread of this process, on its own rclpy context (``cnc-contour run --live``)."""

    def __init__(self, feed: LiveFeed, namespace: str, clock: Callable[[], int] = time.time_ns) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.context = Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)  # the runner's own stay
        self.node = LiveNode(feed, clock, namespace=namespace, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, name="live", daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.1)

    def close(self) -> None:
        """Stop spinning, destroy the node, shut the context down (the caller closes the server)."""
        self._stop.set()
        self.thread.join(timeout=5.0)
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


def main(args: list[str] | None = None) -> None:
    """Console script ``live``."""
    raise SystemExit(spin_node(LiveNode, args))
