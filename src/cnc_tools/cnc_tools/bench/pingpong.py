"""A bare rclpy round trip between two processes: the yardstick of the lockstep graph's hops.

Two roles, each its own process (the bench starts them with the loopback DDS
environment, see :func:`cnc_tools.bench.peers.round_trips`)::

    python -m cnc_tools.bench.pingpong echo --ping T/ping --pong T/pong
    python -m cnc_tools.bench.pingpong ping --ping T/ping --pong T/pong --iterations 2000 --out rtt.json

``echo`` publishes every message it receives on ``--ping`` back on
``--pong``. ``ping`` first publishes until the echo answers (both directions
matched), then runs ``--warmup`` untimed and ``--iterations`` timed round
trips: publish message k, spin until message k comes back. It writes the
round-trip times [s] as JSON to ``--out``. Both sides use the lockstep
graph's QoS (:data:`~cnc_contour_control.nodes.common.LOCKSTEP_QOS`) and the
nodes' executor (``make_executor``, driven by ``spin_once``), so the
round trip holds what one lockstep hop costs without the nodes' own work.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cnc_contour_control.core.lockstep import join_ns, split_ns

#: Exit code of a ping that got no answer in time.
EXIT_TIMEOUT = 3


@dataclass(frozen=True)
class MessageKind:
    """A message type for the round trip and where it carries the sequence number."""

    make: Callable[[], Any]
    set_seq: Callable[[Any, int], None]
    get_seq: Callable[[Any], int]


def _reference() -> Any:
    """A 2-axis Reference as the interpolator publishes it."""
    from cnc_contour_interfaces.msg import Reference

    msg = Reference()
    msg.header.frame_id = "machine"
    msg.axis_names = ["x", "y"]
    msg.position_m, msg.velocity_m_s, msg.acceleration_m_s2 = [0.02, 0.0], [0.0, 0.02], [-0.01, 0.0]
    msg.path_length_m, msg.feed_m_s, msg.programmed_feed_m_s, msg.feed_override_ratio = 0.0, 0.02, 0.02, 1.0
    return msg


def _float64() -> Any:
    from std_msgs.msg import Float64

    return Float64()


def _set_stamp(msg: Any, seq: int) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = split_ns(seq)


def _set_data(msg: Any, seq: int) -> None:
    msg.data = float(seq)


MESSAGES: dict[str, MessageKind] = {
    "reference": MessageKind(_reference, _set_stamp,
                             lambda m: join_ns(m.header.stamp.sec, m.header.stamp.nanosec)),
    "float64": MessageKind(_float64, _set_data, lambda m: int(m.data)),
}


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m cnc_tools.bench.pingpong", description=__doc__.split("\n")[0])
    parser.add_argument("role", choices=("echo", "ping"))
    parser.add_argument("--ping", required=True, help="topic the pinger publishes on")
    parser.add_argument("--pong", required=True, help="topic the echo answers on")
    parser.add_argument("--message", choices=sorted(MESSAGES), default="reference")
    parser.add_argument("--iterations", type=int, default=2000, help="timed round trips")
    parser.add_argument("--warmup", type=int, default=200, help="untimed round trips first")
    parser.add_argument("--timeout-s", type=float, default=10.0, help="wall time to wait for one answer (and the echo)")
    parser.add_argument("--out", type=Path, help="JSON file for the round-trip times (ping)")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Run one role until it is done (ping) or interrupted (echo); return the exit code."""
    from cnc_tools.bench.peers import run_role

    args = _parse(argv)
    return run_role(f"pingpong_{args.role}", lambda node, executor: (
        _echo if args.role == "echo" else _ping)(node, executor, args))


def _echo(node: Any, executor: Any, args: argparse.Namespace) -> int:
    """Answer every ping until shut down."""
    import rclpy

    from cnc_contour_control.nodes.common import LOCKSTEP_QOS

    msg_type = type(MESSAGES[args.message].make())
    pub = node.create_publisher(msg_type, args.pong, LOCKSTEP_QOS)
    node.create_subscription(msg_type, args.ping, pub.publish, LOCKSTEP_QOS)
    while rclpy.ok():
        executor.spin_once(timeout_sec=0.1)
    return 0


class _Pinger:
    """The ping side: one publisher, one subscription, the last sequence number answered."""

    def __init__(self, node: Any, executor: Any, args: argparse.Namespace) -> None:
        from cnc_contour_control.nodes.common import LOCKSTEP_QOS

        self.kind = MESSAGES[args.message]
        self.msg = self.kind.make()
        self.executor = executor
        self.timeout_s = args.timeout_s
        self.answered = -1
        self.pub = node.create_publisher(type(self.msg), args.ping, LOCKSTEP_QOS)
        node.create_subscription(type(self.msg), args.pong, self._on_pong, LOCKSTEP_QOS)

    def _on_pong(self, msg: Any) -> None:
        self.answered = self.kind.get_seq(msg)

    def handshake(self) -> int:
        """Publish until the echo answers (both directions matched); return the next free sequence number."""
        deadline, seq = time.monotonic() + self.timeout_s, 0
        while self.answered < 0:
            if time.monotonic() > deadline:
                raise TimeoutError(f"no echo within {self.timeout_s} s")
            self.kind.set_seq(self.msg, seq)
            self.pub.publish(self.msg)
            self.executor.spin_once(timeout_sec=0.05)
            seq += 1
        return seq

    def round_trip(self, seq: int) -> float:
        """Publish message ``seq`` and spin until it comes back; wall seconds."""
        self.kind.set_seq(self.msg, seq)
        started = time.perf_counter()
        deadline = started + self.timeout_s
        self.pub.publish(self.msg)
        while self.answered != seq:
            remaining = deadline - time.perf_counter()
            if remaining <= 0.0:
                raise TimeoutError(f"round trip {seq} not answered within {self.timeout_s} s")
            self.executor.spin_once(timeout_sec=remaining)
        return time.perf_counter() - started


def _ping(node: Any, executor: Any, args: argparse.Namespace) -> int:
    """Handshake, warm up, time ``args.iterations`` round trips, write them to ``args.out``."""
    pinger = _Pinger(node, executor, args)
    try:
        seq = pinger.handshake()
        for k in range(args.warmup):
            pinger.round_trip(seq + k)
        seq += args.warmup
        times = [pinger.round_trip(seq + k) for k in range(args.iterations)]
    except TimeoutError as err:
        print(f"pingpong: {err}", file=sys.stderr)
        return EXIT_TIMEOUT
    result = {"message": args.message, "iterations": args.iterations, "round_trip_s": times}
    if args.out is not None:
        args.out.write_text(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
