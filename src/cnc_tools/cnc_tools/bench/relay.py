"""A bare relay graph: the lockstep graph's shape with no suite code, the yardstick between it and a ping-pong.

Four roles, each its own process (started with the loopback DDS environment
by :func:`relay_ticks`)::

    python -m cnc_tools.bench.relay plant --ns /T --ticks 1000 --warmup 100 --out relay.json
    python -m cnc_tools.bench.relay interpolator --ns /T
    python -m cnc_tools.bench.relay servo --ns /T --axis x      (and y)

The plant publishes ``joint_states`` (sensor_msgs/JointState, two axes) and
``clock`` (rosgraph_msgs/Clock) at stamp k, and waits for both axes'
``servo/<axis>/command`` (AxisCommand) of stamp k before tick k + 1; the
interpolator answers every joint state with a ``reference`` (Reference) of
its stamp; a servo publishes its command once it holds the joint state and
the reference of a stamp. That is the node graph's topology, message types,
QoS (``LOCKSTEP_QOS``) and executor (``make_executor``, driven by
``spin_once``), with plain rclpy messages and no validation, law, plan or
plant model: what the graph would cost if the nodes did nothing.

The plant first publishes tick 0 until both commands of stamp 0 are back
(every reader matched on both sides), then runs ``--warmup`` untimed and
``--ticks`` timed ticks and writes their wall time as JSON to ``--out``.
"""
from __future__ import annotations

import argparse
import json
import os
import secrets
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.core.lockstep import join_ns, split_ns

#: Exit code of a plant whose commands did not come in time.
EXIT_TIMEOUT = 3
AXES = ("x", "y")
MODULE = "cnc_tools.bench.relay"


def _stamp_ns(msg: Any) -> int:
    return join_ns(msg.header.stamp.sec, msg.header.stamp.nanosec)


def _stamp(msg: Any, stamp_ns: int) -> Any:
    msg.header.stamp.sec, msg.header.stamp.nanosec = split_ns(stamp_ns)
    return msg


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=f"python -m {MODULE}", description=__doc__.split("\n")[0])
    parser.add_argument("role", choices=("plant", "interpolator", "servo"))
    parser.add_argument("--ns", required=True, help="namespace of the relay's topics")
    parser.add_argument("--axis", choices=AXES, help="the servo's axis")
    parser.add_argument("--ticks", type=int, default=1000, help="timed ticks (plant)")
    parser.add_argument("--warmup", type=int, default=100, help="untimed ticks first (plant)")
    parser.add_argument("--sample-time-s", type=float, default=0.001, help="stamp step (plant)")
    parser.add_argument("--timeout-s", type=float, default=30.0, help="wall time a tick may wait (plant)")
    parser.add_argument("--out", type=Path, help="JSON file for the timed ticks' wall time (plant)")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Run one role until it is done (plant) or interrupted; return the exit code."""
    from cnc_tools.bench.peers import run_role

    args = _parse(argv)
    return run_role(f"relay_{args.role}{'_' + args.axis if args.axis else ''}", lambda node, executor: _role(
        node, executor, args), args.ns)


def _role(node: Any, executor: Any, args: argparse.Namespace) -> int:
    import rclpy

    if args.role == "plant":
        return _RelayPlant(node, executor, args).run()
    _answer(node, args)
    while rclpy.ok():
        executor.spin_once(timeout_sec=0.1)
    return 0


def _answer(node: Any, args: argparse.Namespace) -> None:
    """The interpolator's or a servo's subscriptions and publisher."""
    from sensor_msgs.msg import JointState

    from cnc_contour_control.nodes.common import LOCKSTEP_QOS
    from cnc_contour_interfaces.msg import AxisCommand, Reference

    if args.role == "interpolator":
        reference = node.create_publisher(Reference, "reference", LOCKSTEP_QOS)
        template = _reference_msg(Reference)
        node.create_subscription(JointState, "joint_states",
                                 lambda msg: reference.publish(_stamp(template, _stamp_ns(msg))), LOCKSTEP_QOS)
        return
    command = node.create_publisher(AxisCommand, f"servo/{args.axis}/command", LOCKSTEP_QOS)
    out = AxisCommand(axis_name=args.axis, command=0.0, command_unit="dac")
    held: dict[str, dict[int, Any]] = {"joint_states": {}, "reference": {}}

    def take(topic: str) -> Any:
        def on_message(msg: Any) -> None:
            stamp_ns = _stamp_ns(msg)
            held[topic][stamp_ns] = msg
            other = held["reference" if topic == "joint_states" else "joint_states"]
            if stamp_ns in other:
                del other[stamp_ns], held[topic][stamp_ns]
                out.command = float(stamp_ns % 7)
                command.publish(_stamp(out, stamp_ns))

        return on_message

    node.create_subscription(JointState, "joint_states", take("joint_states"), LOCKSTEP_QOS)
    node.create_subscription(Reference, "reference", take("reference"), LOCKSTEP_QOS)


def _reference_msg(reference_type: type) -> Any:
    msg = reference_type()
    msg.header.frame_id = "machine"
    msg.axis_names = list(AXES)
    msg.position_m, msg.velocity_m_s, msg.acceleration_m_s2 = [0.02, 0.0], [0.0, 0.02], [-0.01, 0.0]
    msg.path_length_m, msg.feed_m_s, msg.programmed_feed_m_s, msg.feed_override_ratio = 0.0, 0.02, 0.02, 1.0
    return msg


class _RelayPlant:
    """Publishes a tick, waits for both axes' commands of its stamp, and so on."""

    def __init__(self, node: Any, executor: Any, args: argparse.Namespace) -> None:
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import JointState

        from cnc_contour_control.nodes.common import LOCKSTEP_QOS
        from cnc_contour_interfaces.msg import AxisCommand

        self.executor, self.args = executor, args
        self.step_ns = round(args.sample_time_s * 1e9)
        self.joint_pub = node.create_publisher(JointState, "joint_states", LOCKSTEP_QOS)
        self.clock_pub = node.create_publisher(Clock, "clock", LOCKSTEP_QOS)
        self.state = JointState(name=list(AXES), position=[0.0, 0.0], velocity=[0.0, 0.0])
        self.clock = Clock()
        self.answered: dict[str, int] = dict.fromkeys(AXES, -1)
        for axis in AXES:
            node.create_subscription(AxisCommand, f"servo/{axis}/command", self._on_command(axis), LOCKSTEP_QOS)

    def _on_command(self, axis: str) -> Any:
        def on_command(msg: Any) -> None:
            self.answered[axis] = max(self.answered[axis], _stamp_ns(msg))

        return on_command

    def _publish(self, stamp_ns: int) -> None:
        self.state.position[0] = stamp_ns * 1e-12
        self.joint_pub.publish(_stamp(self.state, stamp_ns))
        self.clock.clock.sec, self.clock.clock.nanosec = split_ns(stamp_ns)
        self.clock_pub.publish(self.clock)

    def _tick(self, stamp_ns: int) -> None:
        """Publish tick ``stamp_ns`` and spin until both commands of it are in."""
        deadline = time.monotonic() + self.args.timeout_s
        self._publish(stamp_ns)
        while min(self.answered.values()) < stamp_ns:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise TimeoutError(f"tick {stamp_ns} ns: commands {self.answered} within {self.args.timeout_s} s")
            self.executor.spin_once(timeout_sec=remaining)

    def _handshake(self) -> None:
        """Publish tick 0 until both commands of it come back (every endpoint matched on both sides)."""
        deadline = time.monotonic() + self.args.timeout_s
        while min(self.answered.values()) < 0:
            if time.monotonic() > deadline:
                raise TimeoutError(f"no commands for tick 0 within {self.args.timeout_s} s: {self.answered}")
            self._publish(0)
            self.executor.spin_once(timeout_sec=0.05)

    def run(self) -> int:
        try:
            self._handshake()
            for k in range(1, self.args.warmup + 1):
                self._tick(k * self.step_ns)
            first = self.args.warmup + 1
            started = time.perf_counter()
            for k in range(first, first + self.args.ticks):
                self._tick(k * self.step_ns)
            wall_s = time.perf_counter() - started
        except TimeoutError as err:
            print(f"relay plant: {err}", file=sys.stderr, flush=True)
            return EXIT_TIMEOUT
        if self.args.out is not None:
            self.args.out.write_text(json.dumps({"ticks": self.args.ticks, "wall_time_s": wall_s}))
        return 0


def relay_ticks(run_dir: Path, ticks: int, warmup: int, timeout_s: float = 120.0,
                namespace: str | None = None) -> float:
    """Wall seconds per tick of ``ticks`` timed lockstep ticks of a fresh relay graph (four processes)
    in ``namespace`` (default: a fresh one).

    Raises
    ------
    FaultError
        A relay process failed, or the plant did not finish within ``timeout_s``; the message names it.
    """
    from cnc_tools.bench.peers import Peers

    ns = namespace or f"/relay_{os.getpid()}_{secrets.token_hex(4)}"
    out = run_dir / "relay.json"
    with Peers(run_dir) as peers:
        peers.start("relay_interpolator", MODULE, ["interpolator", "--ns", ns])
        for axis in AXES:
            peers.start(f"relay_servo_{axis}", MODULE, ["servo", "--ns", ns, "--axis", axis])
        peers.start("relay_plant", MODULE, ["plant", "--ns", ns, "--ticks", str(ticks), "--warmup", str(warmup),
                                            "--out", str(out)])
        code = _wait_plant(peers, timeout_s)
        if code != 0 or not out.exists():
            raise FaultError(f"relay plant failed with exit code {code}: {peers.last_output('relay_plant')!r}")
    result = json.loads(out.read_text())
    return float(result["wall_time_s"]) / int(result["ticks"])


def _wait_plant(peers: Any, timeout_s: float) -> int:
    """The plant's exit code; a FaultError naming a relay process that ended before it."""
    deadline = time.monotonic() + timeout_s
    plant = peers.processes["relay_plant"]
    while time.monotonic() < deadline:
        try:
            return int(plant.wait(timeout=0.2))
        except subprocess.TimeoutExpired:  # look at the others
            dead = {name: p.returncode for name, p in peers.processes.items() if p.poll() is not None}
            if dead:
                raise FaultError(f"relay process {sorted(dead)[0]} ended (exit code {dead[sorted(dead)[0]]}) "
                                 f"before the plant finished: {peers.last_output(sorted(dead)[0])!r}") from None
    raise FaultError(f"relay plant did not finish within {timeout_s} s")


if __name__ == "__main__":
    raise SystemExit(main())
