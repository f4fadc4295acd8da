"""Helpers for tests of real nodes (a probe node on a background executor, socket inspection) and for loading a
test module beside another (pytest runs with ``--import-mode=importlib``).

Used by the suite's own tests and by integrators testing their stack against ours.
"""
from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
import threading
import time
from collections import defaultdict
from collections.abc import Callable, Iterable
from pathlib import Path
from types import ModuleType
from typing import Any

import rclpy
from rclpy.action import ActionClient
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile

from cnc_contour_control.nodes.common import LOCKSTEP_QOS, make_executor


def _events_executor(context: Context) -> Any:
    """``make_executor(context)`` also under pytest's ``capsys``: rclpy's EventsExecutor enables
    ``faulthandler`` on ``sys.stderr``, which must then be a real file."""
    stderr = sys.stderr
    sys.stderr = sys.__stderr__
    try:
        return make_executor(context)
    finally:
        sys.stderr = stderr


class _BackgroundNode:
    """A node in its own context, spun by a daemon thread between ``__enter__`` and ``__exit__``."""

    def _attach(self, context: Context, node: Node, events: bool = False) -> None:
        """``events``: the nodes' executor (``make_executor``), which keeps up with a lockstep graph's rate."""
        self.context, self.node = context, node
        self.executor = _events_executor(context) if events else SingleThreadedExecutor(context=context)
        self.executor.add_node(node)
        self._running = True
        self._thread = threading.Thread(target=self._spin, daemon=True)

    def _spin(self) -> None:
        while self._running and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def __enter__(self) -> Any:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._running = False
        self._thread.join(timeout=5.0)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


class TopicProbe(_BackgroundNode):
    """A node in its own context and thread that records messages and publishes on request.

    ``subscriptions`` maps topic -> message type; ``name`` and ``namespace`` are the node's
    (a probe may stand in for a node of the run). Use as a context manager.
    """

    def __init__(self, subscriptions: dict[str, type], name: str = "probe", qos: QoSProfile = LOCKSTEP_QOS,
                 namespace: str = "") -> None:
        context = Context()
        rclpy.init(context=context)
        # A probe reads every tick of a graph that may run several times faster than real time: a
        # SingleThreadedExecutor (a wait set rebuilt in Python per callback) fell a whole run behind.
        self._attach(context, Node(name, namespace=namespace, context=context), events=True)
        self.messages: dict[str, list[Any]] = defaultdict(list)
        self._lock = threading.Lock()
        self._watchers: dict[str, list[Callable[[Any], None]]] = defaultdict(list)
        for topic, msg_type in subscriptions.items():
            self.node.create_subscription(msg_type, topic, self._recorder(topic), qos)

    def _recorder(self, topic: str) -> Callable[[Any], None]:
        def record(msg: Any) -> None:
            with self._lock:
                self.messages[topic].append(msg)
            for watcher in self._watchers[topic]:
                watcher(msg)

        return record

    def watch(self, topic: str, callback: Callable[[Any], None]) -> None:
        """Call ``callback(msg)`` on the probe's thread for each message of ``topic`` once it is recorded:
        to act at a point of the run (the n-th tick), not at whatever point a polling loop notices it."""
        self._watchers[topic].append(callback)

    def publisher(self, msg_type: type, topic: str, qos: QoSProfile = LOCKSTEP_QOS) -> Any:
        """A publisher on the probe's node."""
        return self.node.create_publisher(msg_type, topic, qos)

    def received(self, topic: str) -> list[Any]:
        """A copy of the messages received on ``topic`` so far."""
        with self._lock:
            return list(self.messages[topic])

    def wait_for(self, condition: Callable[[], bool], timeout_s: float, what: str) -> None:
        """Wait until ``condition()`` holds; raise AssertionError naming ``what`` after ``timeout_s``."""
        wait_until(condition, timeout_s, what)

    def call(self, srv_type: type, name: str, request: Any, timeout_s: float = 30.0) -> Any:
        """Call service ``name`` from the probe's node once it is there; its answer (AssertionError after
        ``timeout_s`` without one)."""
        client = self.node.create_client(srv_type, name)
        self.wait_for(client.service_is_ready, 2 * timeout_s, f"service {name}")
        future = client.call_async(request)
        self.wait_for(future.done, timeout_s, f"answer of {name}")
        return future.result()


#: The least any condition wait waits before it fails, s. A wait's bound only ends a hang: a passing test
#: returns as soon as its condition holds, so the bound costs nothing, while DDS discovery, a service's first
#: answer or a process's start can take tens of seconds beside CPU-bound processes on two cores.
WAIT_FLOOR_S = 90.0


class ThreadSafeActionClient(ActionClient):  # type: ignore[misc]  # rclpy's ActionClient has no type hints
    """rclpy's ``ActionClient`` for a thread that sends while another thread's executor takes the answers.

    Jazzy's rclpy (7.1.5 on PyPI) sends a goal, cancel or result request and only then registers its future, with
    no lock (ros2/rclpy#1123, fixed upstream by #1308). An answer the executor's thread takes in between is logged as
    "Ignoring unexpected ... response" and its future never completes. One lock, held around each send with its
    registration and around each take, closes the gap: a taken answer's request is always registered.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._requests_lock = threading.Lock()

    def take_data(self) -> Any:
        with self._requests_lock:
            return super().take_data()

    def send_goal_async(self, *args: Any, **kwargs: Any) -> Any:
        with self._requests_lock:
            return super().send_goal_async(*args, **kwargs)

    def _cancel_goal_async(self, goal_handle: Any) -> Any:
        with self._requests_lock:
            return super()._cancel_goal_async(goal_handle)

    def _get_result_async(self, goal_handle: Any) -> Any:
        with self._requests_lock:
            return super()._get_result_async(goal_handle)


def wait_until(condition: Callable[[], bool], timeout_s: float, what: str, poll_s: float = 0.01) -> None:
    """Wait until ``condition()`` holds, looking every ``poll_s``; AssertionError naming ``what`` after
    ``timeout_s`` (at least :data:`WAIT_FLOOR_S`)."""
    timeout_s = max(timeout_s, WAIT_FLOOR_S)
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(poll_s)


def udp_sockets(pid: int) -> list[tuple[str, int]]:
    """(local address, port) of every UDP socket process ``pid`` holds (IPv4 and IPv6)."""
    inodes = _socket_inodes(pid)
    sockets = []
    for table, decode in (("udp", _ipv4), ("udp6", _ipv6)):
        path = Path(f"/proc/{pid}/net/{table}")
        if not path.exists():
            continue
        for line in path.read_text().splitlines()[1:]:
            fields = line.split()
            if fields[9] in inodes:
                address, port = fields[1].split(":")
                sockets.append((decode(address), int(port, 16)))
    return sockets


def _socket_inodes(pid: int) -> set[str]:
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    return inodes


def _ipv4(hex_address: str) -> str:
    return ".".join(str(int(hex_address[i:i + 2], 16)) for i in (6, 4, 2, 0))


def _ipv6(hex_address: str) -> str:
    words = [hex_address[i:i + 8] for i in range(0, 32, 8)]
    raw = b"".join(bytes.fromhex(w)[::-1] for w in words)
    import ipaddress

    return str(ipaddress.IPv6Address(raw))


def ephemeral_port_range() -> tuple[int, int]:
    """The kernel's range for ports picked by bind(port=0)."""
    low, high = Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()
    return int(low), int(high)


def dds_ports(domain_id: int, participants: int = 120) -> set[int]:
    """Well-known RTPS ports of a domain (discovery and user unicast/multicast)."""
    base = 7400 + 250 * domain_id
    ports = {base, base + 1}
    for participant in range(participants):
        ports.update({base + 10 + 2 * participant, base + 11 + 2 * participant})
    return ports


def all_alive(pids: Iterable[int]) -> bool:
    """True if every process in ``pids`` is still running."""
    return all(Path(f"/proc/{pid}").exists() for pid in pids)


class InProcessNode(_BackgroundNode):
    """Runs a node class in this process, in its own context, spun by a background thread."""

    def __init__(self, factory: Callable[..., Node], parameters: dict[str, Any], namespace: str = "/cnc") -> None:
        from rclpy.parameter import Parameter

        context = Context()
        rclpy.init(context=context)
        overrides = [Parameter(name, value=value) for name, value in parameters.items()]
        self._attach(context, factory(context=context, namespace=namespace, parameter_overrides=overrides))


def stop_processes(processes: Iterable[subprocess.Popen[Any]], timeout_s: float = 10.0) -> None:
    """SIGINT to every process still running (nodes started by a test), then wait; kill by pid what does not stop."""
    processes = list(processes)
    for process in processes:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
    for process in processes:
        try:
            process.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def sibling_module(test_file: str | Path, name: str) -> ModuleType:
    """The test module ``name`` (without ``.py``) in the folder of ``test_file`` (pass ``__file__``)."""
    path = Path(test_file).with_name(f"{name}.py")
    spec = importlib.util.spec_from_file_location(f"_{name}", path)
    if spec is None or spec.loader is None:
        raise ImportError(f"no test module {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
