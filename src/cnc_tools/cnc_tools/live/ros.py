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
        self.feed = feed or LiveFeed(LiveServer(LiveConfig(host=host, port=int(port))), WINDOW_NS)
        if self.owns_server:
            self.get_logger().info(f"live server on {self.feed.server.url}")
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
