"""What every node of the suite shares: QoS, stamps, parameters, faults, diagnostics, main().

Nodes only translate: they declare parameters, convert messages with the
package's ``conversions`` module and call the ROS-free core.
"""
from __future__ import annotations

import importlib
import signal
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from cnc_contour_control.core.errors import CncError, FaultError, InputFault
from cnc_contour_control.core.lockstep import NS_PER_S, StampMatcher, join_ns, split_ns
from cnc_contour_control.core.stop_signals import StopSignals
from cnc_contour_control.core.topics import RUN_ID_KEY, qualify
from cnc_contour_control.nodes import fast_cdr, local_bus
from cnc_contour_control.nodes.lifecycle import ManagedNode
from cnc_contour_control.nodes.parameters import command_line_rules

#: Lockstep data: reliable and deep, so nothing is dropped while a stage is busy.
LOCKSTEP_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
#: Latched data (the program's path): late joiners get the last message.
LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
#: Exit code of a node that stopped on a fault (bad data, missing input).
EXIT_FAULT = 3
#: A node waiting this long for a partner says so: in the log (throttled to this period) and STALE on /diagnostics.
WAIT_REPORT_AFTER_S = 1.0


def stamp_to_ns(stamp: Time) -> int:
    """builtin_interfaces/Time to integer nanoseconds."""
    return join_ns(stamp.sec, stamp.nanosec)


def ns_to_stamp(stamp_ns: int) -> Time:
    """Integer nanoseconds to builtin_interfaces/Time."""
    stamp = _new_time()
    set_stamp(stamp, stamp_ns)
    return stamp


def set_stamp(stamp: Time, stamp_ns: int) -> None:
    """Set a builtin_interfaces/Time (a message's ``header.stamp``) to integer nanoseconds, in place."""
    stamp.sec, stamp.nanosec = split_ns(stamp_ns)


#: ``Time()`` without rosidl's keyword checks (:func:`fast_cdr.constructor`).
_new_time = fast_cdr.constructor(Time)


def describe(
    text: str,
    low: float | None = None,
    high: float | None = None,
    read_only: bool = False,
    integer: bool = False,
) -> ParameterDescriptor:
    """A parameter descriptor with an optional numeric range."""
    descriptor = ParameterDescriptor(description=text, read_only=read_only)
    if low is not None and high is not None:
        if integer:
            descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=0)]
        else:
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)
            ]
    return descriptor


class ReaderGate:
    """Opens once a writer has matched the readers a run needs, known by node name, not only by count.

    Identities come from the ROS graph (node name and namespace of each
    subscription on the topic), delivery from the writer (its matched-reader
    count). The gate opens when every ``required`` reader is in the graph and
    the writer has matched at least ``min_count`` readers and at least as many
    as the graph shows with a compatible type and QoS, so a foreign listener
    cannot stand in for a required reader. The remaining race is in
    docs/design.md §3.
    """

    def __init__(self, node: Node, publisher: Any, type_name: str, required: Sequence[str], min_count: int) -> None:
        self.node, self.publisher, self.type_name = node, publisher, type_name
        self.required = tuple(sorted({qualify(node.get_namespace(), r) for r in required if r}))
        self.min_count = int(min_count)
        self.created_s = wall_time_s()

    def _graph_readers(self) -> list[Any]:
        infos = self.node.get_subscriptions_info_by_topic(self.publisher.topic_name)
        return [i for i in infos if i.topic_type == self.type_name]

    def missing(self) -> list[str]:
        """Required readers the graph does not show yet, and unmatched ones as a count."""
        readers, local = self._graph_readers(), local_bus.local_readers(self.publisher)  # local: served in process
        present = {qualify(i.node_namespace, i.node_name) for i in readers} | set(local)
        missing = [name for name in self.required if name not in present]
        compatible = sum(1 for i in readers if _delivers(self.publisher.qos_profile, i.qos_profile)) + len(local)
        wanted = max(self.min_count, compatible if self.required else 0)
        matched = self.publisher.get_subscription_count()
        return missing + ([f"{wanted - matched} of {wanted} readers unmatched"] if matched < wanted else [])

    def ready(self) -> bool:
        """True when every required reader is there and matched."""
        return not self.missing()

    def overdue(self, timeout_s: float) -> str | None:
        """What is missing, once the gate has waited longer than ``timeout_s`` since it was made."""
        if wall_time_s() - self.created_s <= timeout_s:
            return None
        missing = self.missing()
        return f"{self.publisher.topic_name} readers missing after {timeout_s} s: {missing}" if missing else None


def _delivers(writer_qos: QoSProfile, reader_qos: QoSProfile) -> bool:
    """True unless the reader asks more than the writer offers (reliability, durability: what our profiles set).

    (rclpy's ``qos_check_compatible`` reads the graph's "infinite" deadline as
    set and the writer's "system default" as unset, and refuses every pair.)
    """
    if reader_qos.reliability == ReliabilityPolicy.RELIABLE and writer_qos.reliability == ReliabilityPolicy.BEST_EFFORT:
        return False
    return not (reader_qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
                and writer_qos.durability == DurabilityPolicy.VOLATILE)


class GatedPublisher:
    """Holds messages until its gate (a :class:`ReaderGate` or a reader count) opens, then publishes in order.

    With volatile durability a reader matched late never sees earlier samples,
    so a lockstep stage publishes nothing before all its readers are there.
    """

    def __init__(self, publisher: Any, min_subscribers: int = 0, gate: ReaderGate | None = None) -> None:
        self.publisher = publisher
        self.min_subscribers = int(min_subscribers)
        self.gate = gate
        self._held: list[Any] = []
        self._open = gate is None and self.min_subscribers <= 0

    def publish(self, msg: Any) -> None:
        """Publish now if the readers are there, else hold."""
        if self._open:  # once open nothing is held: straight through
            self.publisher.publish(msg)
            return
        self._held.append(msg)
        self.flush()

    @property
    def is_open(self) -> bool:
        """True once enough readers were matched (the gate never closes again)."""
        return self._open

    def flush(self) -> None:
        """Publish what is held once the readers are matched (checked until they are)."""
        if not self._open:
            self._open = (self.gate.ready() if self.gate is not None
                          else self.publisher.get_subscription_count() >= self.min_subscribers)
        if self._open:
            for msg in self._held:
                self.publisher.publish(msg)
            self._held.clear()


def command_line_first(kwargs: dict[str, Any], argv: Sequence[str] | None = None) -> dict[str, Any]:
    """A node's constructor arguments with the process's ``-p NAME:=VALUE`` (``argv``, default ``sys.argv``) given
    again as the node's own arguments, so they win over any ``--params-file``.

    rclpy applies a parameters file's ``/<ns>/<node>`` section after its ``/**`` entries, where rcl puts a
    command line's ``-p``: ``--params-file F -p summary_file:=S`` kept F's plant ``summary_file``. A node's own
    arguments come after the process's, so there the rule wins, as a ROS user expects. A node that ignores the
    process's arguments (``use_global_arguments=False``, a composed host's member) is left as it is.
    """
    if not kwargs.get("use_global_arguments", True):
        return kwargs
    rules = command_line_rules(sys.argv if argv is None else argv)
    if not rules:
        return kwargs
    own = list(kwargs.get("cli_args") or [])
    return {**kwargs, "cli_args": [*own, "--ros-args", *(word for rule in rules for word in ("-p", rule))]}


class SuiteNode(ManagedNode):
    """A node that reports faults on ``/diagnostics`` and stops on them; managed if it builds in ``configure``."""

    def __init__(self, name: str, **kwargs: Any) -> None:
        super().__init__(name, **command_line_first(kwargs))
        self.fault_message: str | None = None
        self.finished = False
        self.tick_stamp_ns = 0  # the run's time: the stamp of the last tick this node took in, ns (0 before any)
        self._diagnostics = self.create_publisher(DiagnosticArray, "/diagnostics", 100)
        self.created_s = wall_time_s()
        self._waits: dict[str, str] = {}  # what this node waits for, by who noticed it
        self._checked_topics: dict[str, str] = {}  # resolved names of the topics subscribe_checked took, by topic
        self.create_timer(WAIT_REPORT_AFTER_S, self._report_waits)
        self.start_lifecycle()  # unmanaged: configure and activate now (nodes/lifecycle.py)

    def report_status(self, level: bytes, message: str) -> None:
        """A lifecycle refusal on /diagnostics."""
        self.report(level, message)

    def end_lifecycle(self) -> None:
        """Shutdown transition: the spin loop ends."""
        self.finished = True

    def create_publisher(self, msg_type: Any, topic: str, qos_profile: QoSProfile | int, **kwargs: Any) -> Any:
        """rclpy's publisher; in a composed process with a local bus, wrapped to hand messages to members in process."""
        publisher = super().create_publisher(msg_type, topic, qos_profile, **kwargs)
        bus = local_bus.bus_of(self.context)
        if bus is None or local_bus.is_latched(qos_profile):
            return fast_cdr.fast_publisher(publisher, msg_type)
        return bus.publisher(self, publisher, msg_type)

    def create_subscription(self, msg_type: Any, topic: str, callback: Callable[..., Any],
                            qos_profile: QoSProfile | int, **kwargs: Any) -> Any:
        """rclpy's subscription; in a composed process with a local bus, served by the bus (see ``local_bus``)."""
        bus = local_bus.bus_of(self.context)
        if bus is None or local_bus.is_latched(qos_profile):
            return self.create_dds_subscription(msg_type, topic, callback, qos_profile, **kwargs)
        raw = bool(kwargs.pop("raw", False))
        return bus.subscribe(local_bus.LocalSubscription(self, self.resolve_topic_name(topic), msg_type, callback,
                                                         qos_profile, raw, kwargs))

    def create_dds_subscription(self, msg_type: Any, topic: str, callback: Callable[..., Any],
                                qos_profile: QoSProfile | int, **kwargs: Any) -> Any:
        """rclpy's own subscription, never the bus; raw bytes decoded by ``fast_cdr`` unless the caller asked for
        raw."""
        callback, kwargs = fast_cdr.decoding(msg_type, topic, callback, kwargs, self.fault)
        return super().create_subscription(msg_type, topic, callback, qos_profile, **kwargs)

    def gated_publisher(self, msg_type: type, topic: str, default_min: int) -> GatedPublisher:
        """A lockstep publisher that waits for its readers (parameters ``required_readers``, ``min_subscribers``)."""
        publisher = self.create_publisher(msg_type, topic, LOCKSTEP_QOS)
        gated = GatedPublisher(publisher, gate=self.reader_gate(publisher, msg_type, "min_subscribers", default_min))

        def flush() -> None:
            gated.flush()
            if gated.is_open:
                timer.cancel()
            waiting = gated.gate.missing() if gated.gate is not None and not gated.is_open else []
            self.waiting_for(f"readers:{publisher.topic_name}",
                             f"readers of {publisher.topic_name}: {', '.join(waiting)}" if waiting else None)

        timer = self.create_timer(0.01, flush)
        return gated

    def waiting_for(self, key: str, what: str | None) -> None:
        """Note what this node waits for (``what``), or that it no longer does (None), as noticed by ``key``."""
        if what is None:
            self._waits.pop(key, None)
        else:
            self._waits[key] = what

    def _report_waits(self) -> None:
        """Every second, once up for ``WAIT_REPORT_AFTER_S``: what the node waits for, logged and STALE.

        STALE is no fault (the run's verdict counts ERROR only); it tells a user who starts the nodes by hand
        which partner is missing.
        """
        if self._waits and not self.finished and wall_time_s() - self.created_s >= WAIT_REPORT_AFTER_S:
            message = "waiting for " + "; ".join(self._waits[key] for key in sorted(self._waits))
            self.get_logger().info(message)
            self.report(DiagnosticStatus.STALE, message)

    def publishers_of(self, topic: str) -> str:
        """``/ns/topic: N of 1 publishers``: who a lockstep input waits for, as a user reads it."""
        resolved = self.resolve_topic_name(topic)
        return f"{resolved}: {self.count_publishers(resolved)} of 1 publishers"

    def reader_gate(self, publisher: Any, msg_type: type, count_parameter: str, default_min: int) -> ReaderGate:
        """The gate of ``publisher``: the readers named by ``required_readers``, at least ``count_parameter`` of
        them."""
        topic = publisher.topic_name
        minimum = self.declare(count_parameter, default_min, describe(
            f"readers of {topic} to wait for before publishing", 0, 1000, True, True))
        required = self.declare("required_readers", Parameter.Type.STRING_ARRAY, describe(
            f"node names (relative to the namespace, or absolute) that must read {topic} before it publishes",
            read_only=True))
        return ReaderGate(self, publisher, type_name_of(msg_type), list(required or ()), minimum)

    def subscribe_checked(self, msg_type: type, topic: str, accept: Callable[[Any], Any],
                          then: Callable[[Any], None] | None = None, qos: QoSProfile = LOCKSTEP_QOS) -> Any:
        """Subscribe; a fault while ``accept`` checks a message names the topic; ``then`` gets a non-None result."""
        resolved = self._checked_topics[topic] = self.resolve_topic_name(topic)

        def receive(msg: Any) -> None:
            try:  # a fault while checking names the topic: the one at fault, which may be another input's
                result = accept(msg)
            except InputFault as err:  # (e.g. a held input checked when this one released the first tick)
                raise FaultError(f"{self._checked_topics.get(err.input_name, resolved)}: {err}") from err
            except FaultError as err:
                raise FaultError(f"{resolved}: {err}") from err
            if result is not None:  # taken in (a whole tick, or a message of one): the run has reached its stamp
                self.note_tick(stamp_to_ns(msg.header.stamp))
            if then is not None and result is not None:
                then(result)

        return self.create_subscription(msg_type, topic, self.guarded(receive), qos)

    @property
    def status_publisher(self) -> Any:
        """The publisher of this node's statuses (``/diagnostics``, remapped into the run's namespace by the runner)."""
        return self._diagnostics

    def declare(self, name: str, default: Any, descriptor: ParameterDescriptor) -> Any:
        """Declare a parameter and return its value."""
        return self.declare_parameter(name, default, descriptor).value

    def note_tick(self, stamp_ns: int) -> None:
        """The run has reached ``stamp_ns`` (a tick this node took in); its statuses are stamped so from now."""
        self.tick_stamp_ns = max(self.tick_stamp_ns, stamp_ns)

    def run_stamp_ns(self) -> int:
        """The stamp of a status given without one: the run's time (the last tick's stamp, 0 before the first)."""
        return self.tick_stamp_ns

    def report(self, level: bytes, message: str, values: dict[str, str] | None = None,
               stamp_ns: int | None = None) -> None:
        """Publish one status of this node on /diagnostics, stamped ``stamp_ns``, else :meth:`run_stamp_ns`.

        Every status of a run is in the run's (simulation) time, never the wall clock: a waiting or fault
        status sorts with the run's messages.
        """
        status = DiagnosticStatus(
            level=level,
            name=self.get_fully_qualified_name(),
            message=message,
            hardware_id="cnc_contour",
            values=[KeyValue(key=k, value=v) for k, v in {RUN_ID_KEY: self.get_namespace(), **(values or {})}.items()],
        )
        array = DiagnosticArray(status=[status])
        array.header.stamp = ns_to_stamp(self.run_stamp_ns() if stamp_ns is None else stamp_ns)
        self._diagnostics.publish(array)

    def fault(self, message: str) -> None:
        """Report a fault on /diagnostics and the log, and stop the node."""
        first = self.fault_message is None
        self.finished = True  # before the report: whoever sees the report sees a finished node
        if first:
            self.fault_message = message
            self.get_logger().error(f"FAULT: {message}")
            self.report(DiagnosticStatus.ERROR, message)

    def subscribe_matched(self, matcher: StampMatcher, msg_type: type, topic: str, decode: Callable[[Any], Any],
                          then: Callable[[dict[str, Any]], None]) -> Any:
        """A lockstep input: each message decoded and checked first, then matched by stamp; ``then`` gets a whole tick.

        The values are decoded before the stamp is looked at, so a bad message
        is a fault even when it is stale.
        """

        def accept(msg: Any) -> dict[str, Any] | None:
            values = decode(msg)
            return matcher.add(topic, stamp_to_ns(msg.header.stamp), values, wall_time_s())

        return self.subscribe_checked(msg_type, topic, accept, then=then)

    def watch_inputs(self, matcher: StampMatcher, who: str) -> None:
        """Every 0.1 s: a tick whose inputs are overdue is a fault naming ``who``, the tick and the missing topics."""

        def check() -> None:
            missing_inputs = matcher.waiting_for(wall_time_s(), WAIT_REPORT_AFTER_S)
            self.waiting_for(f"inputs:{who}", "; ".join(self.publishers_of(name) for name in missing_inputs) or None)
            overdue = matcher.overdue(wall_time_s())
            if overdue is not None:
                stamp_ns, missing = overdue
                topics = ", ".join(self.resolve_topic_name(name) for name in missing)
                self.fault(f"{who}: no {topics} for tick t={stamp_ns / NS_PER_S:.6f} s "
                           f"within {matcher.current_timeout_s} s")

        self.create_timer(0.1, self.guarded(check))

    def guarded(self, callback: Callable[..., None]) -> Callable[..., None]:
        """Wrap a callback so a suite error becomes a fault, not a traceback."""

        def run(*args: Any) -> None:
            if self.finished or StopSignals.stopping():  # a stopping process only winds down (no late faults)
                return
            try:
                callback(*args)
            except CncError as err:
                self.fault(str(err))

        return run


def type_name_of(msg_type: type) -> str:
    """``pkg/msg/Name`` of an rclpy message class."""
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


def message_class(type_name: str, topic: str = "") -> type:
    """The rclpy message class of ``pkg/msg/Name``; a CncError naming it if this environment lacks it."""
    package, _, name = type_name.split("/") if type_name.count("/") == 2 else ("", "", type_name)
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError, TypeError, ValueError) as err:
        raise CncError(f"message type {type_name!r} of {topic or 'a topic'} is not available "
                       f"in this ROS environment ({type(err).__name__}: {err})") from err


def make_executor(context: Any) -> Any:
    """The executor of a node process: rclpy's EventsExecutor unless CNC_EXECUTOR=single.

    The events executor keeps its ready-queue in C++ instead of rebuilding a
    wait set per callback, which is most of a lockstep tick's cost in Python.
    """
    import os

    if os.environ.get("CNC_EXECUTOR", "events") == "single":
        return SingleThreadedExecutor(context=context)
    from rclpy.experimental import EventsExecutor

    return EventsExecutor(context=context)


def wall_time_s() -> float:
    """Monotonic wall time, for watchdogs only (never for the control laws)."""
    return time.monotonic()


def init_ros(stop: StopSignals, args: Sequence[str] | None) -> None:
    """``rclpy.init`` without rclpy's signal handlers when ``stop``'s are installed (the main thread)."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO if stop.installed else None)


def spin_node(factory: Callable[[], SuiteNode], args: Sequence[str] | None = None) -> int:
    """Run a node until it finishes, faults or is stopped; return the exit code.

    0 when it finished or was stopped (SIGINT, SIGTERM: no traceback, the
    node destroyed: the plant writes ``interrupted``, the recorder closes its
    bag), :data:`EXIT_FAULT` after a fault.
    """
    node: SuiteNode | None = None
    code = 0
    with StopSignals() as stop:
        init_ros(stop, args)
        try:
            node = factory()
            executor = make_executor(node.context)
            executor.add_node(node)
            while rclpy.ok() and not node.finished and not stop.requested:
                executor.spin_once(timeout_sec=0.1)
            code = EXIT_FAULT if node.fault_message else 0
        except (KeyboardInterrupt, ExternalShutdownException):
            code = 0
        except CncError as err:
            print(f"FAULT: {err}", file=sys.stderr, flush=True)
            code = EXIT_FAULT
        finally:
            if node is not None:
                flush_and_destroy(node, flush=not stop.requested)
            rclpy.try_shutdown()
    if stop.requested and stop.installed:  # stopping: a second signal during the interpreter's exit is no kill
        for signum in stop.signals:
            signal.signal(signum, signal.SIG_IGN)
    return code


def flush_and_destroy(node: SuiteNode, flush: bool = True) -> None:
    """Wait (bounded) until every reader acknowledged what this node published, then destroy it (a node's exit).

    ``flush=False`` (stopped by a signal): destroy at once, as the partners are stopping too.
    """
    if node.fault_message:
        print(f"FAULT: {node.fault_message}", file=sys.stderr, flush=True)
    # After a fault, readers may be gone: wait briefly so the diagnostic still leaves.
    timeout = Duration(seconds=0.3 if node.fault_message else 2.0)
    try:
        if flush and node.context.ok():  # a context shut down from outside flushes nothing
            for publisher in list(node.publishers):
                publisher.wait_for_all_acked(timeout)
    except RuntimeError:  # rclpy's RCLError: the context was shut down meanwhile
        pass
    finally:
        node.destroy_node()  # always: the recorder closes its bag here
