"""A node's safety interface: the e-stop topic, ``~/enable`` and ``~/reset``, and per-second diagnostics.

The logic is :class:`~cnc_contour_control.axis.safety.EstopLatch` and
:class:`~cnc_contour_control.core.tick_stats.TickStats`; this module only wires
them to ROS: ``estop`` (std_msgs/Bool, true = e-stop), ``~/enable``
(std_srvs/SetBool), ``~/reset`` (std_srvs/Trigger). A node that may trip the
machine (``trips_machine``: a servo with ``ferror_action: latch``) also
publishes ``estop`` (:meth:`SafetyInterface.trip_machine`). Every change of the latch
and every closed statistics window is a status on ``/diagnostics`` stamped in
the run's time, so the recorder puts it in the bag. :class:`PartnerMonitor`
feeds the publishers of a node's lockstep inputs to
:class:`~cnc_contour_control.axis.safety.PartnerWatch`.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

from diagnostic_msgs.msg import DiagnosticStatus
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, Trigger

from cnc_contour_control.axis.safety import EstopLatch, FerrorTrip, LatchAnswer, PartnerWatch
from cnc_contour_control.core.tick_stats import TickStats
from cnc_contour_control.core.topics import qualify
from cnc_contour_control.nodes.common import SuiteNode

#: Message of the per-second status (diagnostic_updater's periodic status).
RUNNING = "running"


class SafetyInterface:
    """Serves ``latch`` on ``node``; ``stamp_ns`` gives the run's current stamp for the statuses.

    With ``trips_machine`` the node can e-stop the whole machine (:meth:`trip_machine`).
    """

    def __init__(self, node: SuiteNode, latch: EstopLatch, stamp_ns: Callable[[], int],
                 trips_machine: bool = False) -> None:
        self.node, self.latch, self.stamp_ns = node, latch, stamp_ns
        self.stats = TickStats()
        node.create_subscription(Bool, "estop", node.guarded(self._on_estop), 10)
        self._estop_pub = node.create_publisher(Bool, "estop", 10) if trips_machine else None
        node.create_service(SetBool, "~/enable", self._on_enable)
        node.create_service(Trigger, "~/reset", self._on_reset)

    def _on_estop(self, msg: Bool) -> None:
        """An e-stop message: true latches (once), false only clears the input."""
        stamp_ns = self.stamp_ns()
        cause = f"{self.node.resolve_topic_name('estop')} true at t={stamp_ns / 1e9:.6f} s"
        if self.latch.estop(bool(msg.data), cause):
            self.latched(cause)
        elif not msg.data:
            self._report(self._level(), "e-stop input released" + (", reset to clear the latch"
                                                                     if self.latch.latched else ""))

    def latched(self, cause: str) -> None:
        """Log and report that the latch was set by ``cause`` (the e-stop input, or a fault the node tripped)."""
        self.node.get_logger().warning(f"e-stop latched: {cause}")
        self._report(DiagnosticStatus.WARN, f"e-stop latched: {cause}")

    def trip_machine(self, trip: FerrorTrip) -> None:
        """A following-error trip latched this node: ERROR on /diagnostics, then the machine's e-stop.

        The e-stop goes true, then false (LinuxCNC: the error turns the machine off; the cause is gone once the
        axis stands, so a reset is allowed). The status goes first, so who watches both learns the cause first.
        """
        self.node.get_logger().error(f"machine stopped: {trip.message}")
        self._report(DiagnosticStatus.ERROR, f"machine stopped: {trip.message}", trip.values())
        if self._estop_pub is not None:
            self._estop_pub.publish(Bool(data=True))
            self._estop_pub.publish(Bool(data=False))

    def _on_enable(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        """``~/enable``: on refused while latched, with the cause."""
        return self._answer(self.latch.enable(bool(request.data)), response)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """``~/reset``: refused while the e-stop input is still true."""
        return self._answer(self.latch.reset(), response)

    def _answer(self, answer: LatchAnswer, response: SetBool.Response | Trigger.Response) -> object:
        response.success, response.message = answer.accepted, answer.message
        self._report(self._level(), answer.message)
        return response

    def _level(self) -> bytes:
        return DiagnosticStatus.OK if self.latch.commands_allowed else DiagnosticStatus.WARN

    def _report(self, level: bytes, message: str, values: dict[str, str] | None = None) -> None:
        if not self.node.finished:
            self.node.report(level, message, {**self.latch.state(), **(values or {})}, stamp_ns=self.stamp_ns())

    def account(self, stamp_ns: int, wall_s: float, counts: dict[str, tuple[int, int]] | None = None,
                peaks: dict[str, float] | None = None) -> None:
        """Account one tick; at each second of run time publish the window (and the latch's state)."""
        values = self.stats.add(stamp_ns, wall_s, counts, peaks)
        if values is not None and not self.node.finished:
            self.node.report(self._level(), RUNNING, {**values, **self.latch.state()}, stamp_ns=stamp_ns)


#: What rmw reports for an endpoint whose node discovery has not named yet.
UNKNOWN_NODE = "_NODE_NAME_UNKNOWN_"


def publisher_nodes(node: SuiteNode, topic: str) -> list[str | None]:
    """Fully qualified names of the nodes publishing ``topic`` (a resolved name) now; None for one not yet named."""
    return [None if info.node_name == UNKNOWN_NODE else qualify(info.node_namespace, info.node_name)
            for info in node.get_publishers_info_by_topic(topic)]


#: Wall seconds between two looks at the watched topics (a node that exits is found within this, plus discovery).
PARTNER_POLL_S = 0.25


class PartnerMonitor:
    """Every :data:`PARTNER_POLL_S` while ``waiting()``: ``on_lost(message)`` once a topic's publishers all left.

    ``topics`` are the node's lockstep inputs (relative or absolute names).
    A look costs one publisher count per topic (``count_publishers``, about
    20 us); the publishers' names (``get_publishers_info_by_topic``, about
    250 us) are read only when a count changed or a publisher is not named
    yet. (A publisher replaced by another between two looks keeps the old
    name until the count changes: only the fault's wording depends on it.)
    """

    def __init__(self, node: SuiteNode, topics: Sequence[str], waiting: Callable[[], bool],
                 on_lost: Callable[[str], None], stamp_ns: Callable[[], int]) -> None:
        self.node, self.waiting, self.on_lost, self.stamp_ns = node, waiting, on_lost, stamp_ns
        self.watch = PartnerWatch([node.resolve_topic_name(topic) for topic in topics])
        self._named: dict[str, list[str | None]] = {topic: [] for topic in self.watch.topics}
        node.create_timer(PARTNER_POLL_S, node.guarded(self.check))

    def check(self) -> None:
        """Look at the publishers of every watched topic; report the first loss while a tick waits."""
        waiting = self.waiting()
        for topic in self.watch.topics:
            lost = self.watch.observe(topic, self.publishers(topic), self.stamp_ns())
            if lost is not None and waiting:
                self.on_lost(lost)
                return

    def publishers(self, topic: str) -> list[str | None]:
        """The publishing nodes of ``topic`` now: counted, and named again only when the count changed."""
        count = self.node.count_publishers(topic)
        known = self._named[topic]
        if count == 0 or (count == len(known) and None not in known):
            return known if count else []
        self._named[topic] = publisher_nodes(self.node, topic)
        return self._named[topic]

    def last_publishers(self, topic: str) -> str:
        """`` (last published by N)`` for a resolved ``topic``, or nothing when none was seen."""
        nodes = self.watch.publishers(topic) if topic in self.watch.topics else ()
        return f" (last published by {', '.join(nodes)})" if nodes else ""
