"""What every node of the suite shares: QoS, stamps, parameters, faults, diagnostics, main().

Nodes only translate: they declare parameters, convert messages with the
package's ``conversions`` module and call the ROS-free core.
"""
from __future__ import annotations

import importlib
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from cnc_contour_control.errors import CncError, FaultError
from cnc_contour_control.lockstep import join_ns, split_ns

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


def stamp_to_ns(stamp: Time) -> int:
    """builtin_interfaces/Time to integer nanoseconds."""
    return join_ns(stamp.sec, stamp.nanosec)


def ns_to_stamp(stamp_ns: int) -> Time:
    """Integer nanoseconds to builtin_interfaces/Time."""
    sec, nanosec = split_ns(stamp_ns)
    return Time(sec=sec, nanosec=nanosec)


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


class GatedPublisher:
    """Holds messages until the writer has matched ``min_subscribers`` readers, then publishes in order.

    With volatile durability a reader matched late never sees earlier samples,
    so a lockstep stage publishes nothing before all its readers are there.
    """

    def __init__(self, publisher: Any, min_subscribers: int) -> None:
        self.publisher = publisher
        self.min_subscribers = int(min_subscribers)
        self._held: list[Any] = []
        self._open = self.min_subscribers <= 0

    def publish(self, msg: Any) -> None:
        """Publish now if the readers are there, else hold."""
        self._held.append(msg)
        self.flush()

    @property
    def is_open(self) -> bool:
        """True once enough readers were matched (the gate never closes again)."""
        return self._open

    def flush(self) -> None:
        """Publish what is held once enough readers are matched (checked until they are)."""
        if not self._open and self.publisher.get_subscription_count() >= self.min_subscribers:
            self._open = True
        if self._open:
            for msg in self._held:
                self.publisher.publish(msg)
            self._held.clear()


class SuiteNode(Node):
    """A node that reports faults on ``/diagnostics`` and stops on them."""

    def __init__(self, name: str, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.fault_message: str | None = None
        self.finished = False
        self._diagnostics = self.create_publisher(DiagnosticArray, "/diagnostics", 100)

    def gated_publisher(self, msg_type: type, topic: str, default_min: int) -> GatedPublisher:
        """A lockstep publisher that waits for ``min_subscribers`` matched readers (a parameter)."""
        minimum = self.declare("min_subscribers", default_min, describe(
            f"readers of {topic} to wait for before publishing", 0, 1000, True, True))
        gated = GatedPublisher(self.create_publisher(msg_type, topic, LOCKSTEP_QOS), minimum)
        timer = self.create_timer(0.01, lambda: gated.flush() or (gated.is_open and timer.cancel()))
        return gated

    def declare(self, name: str, default: Any, descriptor: ParameterDescriptor) -> Any:
        """Declare a parameter and return its value."""
        return self.declare_parameter(name, default, descriptor).value

    def report(self, level: bytes, message: str, values: dict[str, str] | None = None) -> None:
        """Publish one status of this node on /diagnostics."""
        status = DiagnosticStatus(
            level=level,
            name=self.get_fully_qualified_name(),
            message=message,
            hardware_id="cnc_contour",
            values=[KeyValue(key=k, value=v) for k, v in (values or {}).items()],
        )
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diagnostics.publish(array)

    def fault(self, message: str) -> None:
        """Report a fault on /diagnostics and the log, and stop the node."""
        first = self.fault_message is None
        self.finished = True  # before the report: whoever sees the report sees a finished node
        if first:
            self.fault_message = message
            self.get_logger().error(f"FAULT: {message}")
            self.report(DiagnosticStatus.ERROR, message)

    def guarded(self, callback: Callable[..., None]) -> Callable[..., None]:
        """Wrap a callback so a suite error becomes a fault, not a traceback."""

        def run(*args: Any) -> None:
            if self.finished:
                return
            try:
                callback(*args)
            except CncError as err:
                self.fault(str(err))

        return run


def message_class(type_name: str, topic: str = "") -> type:
    """The rclpy message class of ``pkg/msg/Name``; a CncError naming it if this environment lacks it."""
    package, _, name = type_name.split("/") if type_name.count("/") == 2 else ("", "", type_name)
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)  # type: ignore[no-any-return]
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


def spin_node(factory: Callable[[], SuiteNode], args: Sequence[str] | None = None) -> int:
    """Run a node until it finishes, faults or is interrupted; return the exit code."""
    rclpy.init(args=args)
    node: SuiteNode | None = None
    code = 0
    try:
        node = factory()
        executor = make_executor(node.context)
        executor.add_node(node)
        while rclpy.ok() and not node.finished:
            executor.spin_once(timeout_sec=0.1)
        code = EXIT_FAULT if node.fault_message else 0
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 0
    except CncError as err:
        print(f"FAULT: {err}", file=sys.stderr, flush=True)
        code = EXIT_FAULT
    finally:
        if node is not None:
            _flush_and_destroy(node)
        rclpy.try_shutdown()
    return code


def _flush_and_destroy(node: SuiteNode) -> None:
    """Wait (bounded) until every reader acknowledged what this node published, then destroy it."""
    if node.fault_message:
        print(f"FAULT: {node.fault_message}", file=sys.stderr, flush=True)
    # After a fault, readers may be gone: wait briefly so the diagnostic still leaves.
    timeout = Duration(seconds=0.3 if node.fault_message else 2.0)
    if node.context.ok():  # after SIGINT/SIGTERM the context is gone and nothing can be flushed
        for publisher in list(node.publishers):
            publisher.wait_for_all_acked(timeout)
    node.destroy_node()


def require(condition: bool, message: str) -> None:
    """Raise a :class:`FaultError` with ``message`` unless ``condition`` holds."""
    if not condition:
        raise FaultError(message)
