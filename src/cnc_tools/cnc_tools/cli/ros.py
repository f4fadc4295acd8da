"""``cnc-contour ros``: the ROS command-line tools a wheel install lacks (Jazzy's PyPI wheels carry no ``ros2``).

    cnc-contour ros nodes                              # the graph's nodes, /ns/name
    cnc-contour ros topics [-t]                        # its topics [with their types]
    cnc-contour ros echo /cnc/joint_states [--once] [--csv]
    cnc-contour ros hz /cnc/joint_states [--duration-s 5]
    cnc-contour ros param get|describe /cnc/servo_x gains.kp
    cnc-contour ros param set /cnc/servo_x gains.kp 3.0
    cnc-contour ros action send part.ngc               # cnc-contour send-program: feedback, Ctrl-C cancels
    cnc-contour ros lifecycle get /cnc/servo_x         # its state (unconfigured, inactive, active)
    cnc-contour ros lifecycle set /cnc/servo_x cleanup # configure, cleanup, activate, deactivate, shutdown

Where the real ``ros2`` exists (a system Jazzy), use it; these cover what a
user of this suite needs, with the suite's own message types: a topic's type
is read from the graph and its class imported by name (``pkg/msg/Type``,
:func:`~cnc_contour_control.nodes.common.message_class`). DDS stays on this
machine (:mod:`cnc_tools.runs.dds`), in ``ROS_DOMAIN_ID`` (``./dev shell``
prints it; join a run's domain with ``ROS_DOMAIN_ID=N``). The graph is read
once it stops changing (discovery) or after ``--wait-s``. Exit codes: 0 done,
1 nothing came or a parameter was refused, 2 a bad argument or nothing to
talk to, 130 Ctrl-C.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

import yaml

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.cli import send_program as send_program_cli
from cnc_tools.runs.dds import apply_loopback_policy

#: The graph is taken as discovered once it has not changed for ``--settle-s`` (default SETTLE_S), and no sooner
#: than DISCOVERY_S after the tool's start. Measured with paper 000's graph in-process on the shared 2-core host:
#: a new participant names the four nodes after 2.2-2.9 s, up to 1.7 s apart.
SETTLE_S = 2.0
DISCOVERY_S = 2.0
#: Exit code after Ctrl-C (128 + SIGINT).
EXIT_INTERRUPTED = 130
#: Queue depth of echo's and hz's subscription.
DEPTH = 100
#: The lifecycle transitions ``lifecycle set`` takes (rcl's labels: shutdown from whichever state the node is in).
TRANSITIONS = ("configure", "cleanup", "activate", "deactivate", "shutdown")


def configure(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="ros_command", required=True, metavar="COMMAND")
    nodes = sub.add_parser("nodes", help="the graph's nodes")
    nodes.add_argument("-a", "--all", action="store_true", help="with hidden nodes (names starting with _)")
    topics = sub.add_parser("topics", help="the graph's topics")
    topics.add_argument("-t", "--show-types", action="store_true", help="with their message types")
    echo = sub.add_parser("echo", help="print a topic's messages (YAML, or CSV rows)")
    echo.add_argument("topic")
    echo.add_argument("--once", action="store_true", help="the first message only")
    echo.add_argument("--csv", action="store_true", help="one CSV row per message, a header row first")
    echo.add_argument("--count", type=int, default=0, help="stop after this many messages (default 0: Ctrl-C)")
    hz = sub.add_parser("hz", help="a topic's message rate (each second, and at the end)")
    hz.add_argument("topic")
    hz.add_argument("--duration-s", type=float, default=0.0, help="stop after this wall time (default 0: Ctrl-C)")
    hz.add_argument("--window", type=int, default=10_000, help="periods the statistics cover (default 10000)")
    param = sub.add_parser("param", help="get, set or describe a node's parameter")
    param.add_argument("verb", choices=("get", "set", "describe"))
    param.add_argument("node", help="the node's full name, e.g. /cnc/servo_x")
    param.add_argument("name", help="the parameter, e.g. gains.kp")
    param.add_argument("value", nargs="?", help="set: the value, read as YAML (3.0, true, '[1, 2]', text)")
    lifecycle = sub.add_parser("lifecycle", help="a lifecycle node's state, or a transition")
    lifecycle.add_argument("verb", choices=("get", "set"))
    lifecycle.add_argument("node", help="the node's full name, e.g. /cnc/servo_x")
    lifecycle.add_argument("transition", nargs="?", choices=TRANSITIONS,
                           help="set: the transition (by its label, as ros2 lifecycle set takes it)")
    for tool in (nodes, topics, echo, hz, param, lifecycle):
        tool.add_argument("--wait-s", type=float, default=5.0,
                          help="wall time to wait for the graph, a topic or a node's service (default 5)")
    for tool in (nodes, topics):
        tool.add_argument("--settle-s", type=float, default=SETTLE_S,
                          help=f"the graph is read once unchanged this long (default {SETTLE_S}), s")
    action = sub.add_parser("action", help="RunProgram goals")
    action_sub = action.add_subparsers(dest="action_command", required=True, metavar="COMMAND")
    send = action_sub.add_parser("send", help="cnc-contour send-program: feedback printed, Ctrl-C cancels")
    send_program_cli.configure(send)


def ros(args: argparse.Namespace) -> int:
    """Run the chosen tool on a node of its own (hidden: ``_cnc_contour_ros_<pid>``)."""
    apply_loopback_policy(os.environ)
    if args.ros_command == "action":
        return send_program_cli.send_program(args)
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)  # Ctrl-C: a KeyboardInterrupt here
    node = rclpy.create_node(f"_cnc_contour_ros_{os.getpid()}")
    try:
        return TOOLS[args.ros_command](node, args)
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def settled(node: Any, query: Callable[[], Any], wait_s: float, settle_s: float = SETTLE_S) -> Any:
    """``query()`` once it has not changed for ``settle_s`` after DISCOVERY_S, or as it is after ``wait_s``."""
    import rclpy

    start_s = since_s = time.monotonic()
    last = None
    while True:
        rclpy.spin_once(node, timeout_sec=0.05)
        now_s, value = time.monotonic(), query()
        if value != last:
            last, since_s = value, now_s
        elif value and now_s - since_s >= settle_s and now_s - start_s >= DISCOVERY_S or now_s - start_s >= wait_s:
            return value


def nodes(node: Any, args: argparse.Namespace) -> int:
    names = settled(node, lambda: sorted(f"{ns.rstrip('/')}/{name}" for name, ns in
                                         node.get_node_names_and_namespaces()), args.wait_s, args.settle_s)
    shown = [n for n in names if args.all or not n.rsplit("/", 1)[-1].startswith("_")]
    print("\n".join(shown), flush=True)
    return 0 if shown else 1


def topics(node: Any, args: argparse.Namespace) -> int:
    found = settled(node, lambda: sorted((name, tuple(types)) for name, types in node.get_topic_names_and_types()),
                    args.wait_s, args.settle_s)
    for name, types in found:
        print(f"{name} [{', '.join(types)}]" if args.show_types else name, flush=True)
    return 0 if found else 1


def topic_type(node: Any, topic: str, wait_s: float) -> str:
    """The one message type of ``topic`` in the graph (waiting up to ``wait_s`` for it to appear)."""
    import rclpy

    deadline_s = time.monotonic() + wait_s
    while time.monotonic() < deadline_s:
        types = dict(node.get_topic_names_and_types()).get(topic)
        if types:
            if len(types) > 1:
                raise ConfigError(f"{topic} has {len(types)} types in the graph: {', '.join(types)}")
            return str(types[0])
        rclpy.spin_once(node, timeout_sec=0.05)
    raise ConfigError(f"no topic {topic} in the graph within --wait-s {wait_s} s "
                      f"(cnc-contour ros topics lists them; is ROS_DOMAIN_ID the graph's?)")


def subscribe(node: Any, topic: str, wait_s: float, callback: Callable[[Any], None], raw: bool = False) -> str:
    """Subscribe ``topic`` with its graph type and a QoS every publisher of it matches; the type's name."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from cnc_contour_control.nodes.common import message_class

    type_name = topic_type(node, topic, wait_s)
    publishers = node.get_publishers_info_by_topic(topic)
    reliable = bool(publishers) and all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in publishers)
    latched = bool(publishers) and all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                                       for p in publishers)
    qos = QoSProfile(depth=DEPTH,
                     reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
    node.create_subscription(message_class(type_name, topic), topic, callback, qos, raw=raw)
    return type_name


def message_fields(msg: Any) -> Any:
    """A message as plain values (nested dicts, lists), in its fields' order."""
    if not hasattr(msg, "get_fields_and_field_types"):
        if isinstance(msg, (bytes, bytearray)):
            return list(msg)  # a byte array field: its values
        if hasattr(msg, "tolist"):
            return msg.tolist()  # a numpy or array.array field
        if isinstance(msg, (list, tuple)):
            return [message_fields(item) for item in msg]  # a sequence of messages or strings
        return msg  # a scalar
    return {name: message_fields(getattr(msg, name)) for name in msg.get_fields_and_field_types()}


def flat_fields(values: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """CSV columns: ``header.stamp.sec``, ``position.0``..."""
    if isinstance(values, dict):
        for key, value in values.items():
            yield from flat_fields(value, f"{prefix}{key}.")
    elif isinstance(values, list):
        for index, value in enumerate(values):
            yield from flat_fields(value, f"{prefix}{index}.")
    else:
        yield prefix.rstrip("."), values


def echo(node: Any, args: argparse.Namespace) -> int:
    import csv

    import rclpy

    wanted = 1 if args.once else args.count
    seen: list[int] = [0]
    writer = csv.writer(sys.stdout)
    columns: list[str] = []

    def show(msg: Any) -> None:
        if wanted and seen[0] >= wanted:
            return
        seen[0] += 1
        values = message_fields(msg)
        if args.csv:
            row = dict(flat_fields(values))
            if not columns:
                columns.extend(row)
                writer.writerow(columns)
            writer.writerow([row.get(column, "") for column in columns])
        else:
            sys.stdout.write(yaml.safe_dump(values, sort_keys=False, width=120) + "---\n")
        sys.stdout.flush()

    subscribe(node, args.topic, args.wait_s, show)
    while rclpy.ok() and not (wanted and seen[0] >= wanted):
        rclpy.spin_once(node, timeout_sec=0.1)
    return 0


class RateStats:
    """Arrival times of a topic's messages and their rate (ROS-free)."""

    def __init__(self, window: int) -> None:
        self.window, self.count = window, 0
        self.times_s: list[float] = []

    def add(self, now_s: float) -> None:
        self.count += 1
        self.times_s = [*self.times_s[-self.window:], now_s]

    def describe(self) -> str:
        """``average rate: 100.000 Hz`` with the periods' min, max and std dev over the window."""
        periods = [b - a for a, b in zip(self.times_s, self.times_s[1:])]
        if not periods:
            return f"{self.count} messages: no rate yet"
        mean_s = sum(periods) / len(periods)
        std_s = math.sqrt(sum((p - mean_s) ** 2 for p in periods) / len(periods))
        return (f"average rate: {1.0 / mean_s:.3f} Hz\n"
                f"\tmin: {min(periods):.6f} s max: {max(periods):.6f} s std dev: {std_s:.6f} s "
                f"window: {len(periods) + 1}")


def hz(node: Any, args: argparse.Namespace) -> int:
    import rclpy

    stats = RateStats(args.window)
    subscribe(node, args.topic, args.wait_s, lambda _msg: stats.add(time.monotonic()), raw=True)
    first_s = time.monotonic()  # the duration counts from the first message: matching a new reader takes seconds
    while rclpy.ok() and stats.count == 0 and time.monotonic() - first_s < args.wait_s:
        rclpy.spin_once(node, timeout_sec=0.05)
    start_s = last_s = time.monotonic()
    try:
        while rclpy.ok() and not (args.duration_s and time.monotonic() - start_s >= args.duration_s):
            rclpy.spin_once(node, timeout_sec=0.05)
            if time.monotonic() - last_s >= 1.0:
                last_s = time.monotonic()
                print(stats.describe(), flush=True)
    except KeyboardInterrupt:
        pass
    print(stats.describe(), flush=True)
    return 0 if stats.count >= 2 else 1


def param(node: Any, args: argparse.Namespace) -> int:
    from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters

    target = args.node if args.node.startswith("/") else f"/{args.node}"
    if args.verb == "get":
        values = _call(node, GetParameters, f"{target}/get_parameters", GetParameters.Request(names=[args.name]),
                       args.wait_s).values
        return _print_value(target, args.name, values[0] if values else None)
    if args.verb == "describe":
        described = _call(node, DescribeParameters, f"{target}/describe_parameters",
                          DescribeParameters.Request(names=[args.name]), args.wait_s).descriptors
        if not described:
            raise ConfigError(f"{target} has no parameter {args.name}")
        print(describe_text(described[0]), flush=True)
        return 0
    if args.value is None:
        raise ConfigError("param set needs a VALUE (read as YAML: 3.0, true, '[1, 2]', text)")
    request = SetParameters.Request(parameters=[parameter_msg(args.name, args.value)])
    result = _call(node, SetParameters, f"{target}/set_parameters", request, args.wait_s).results[0]
    if not result.successful:
        print(f"{target} {args.name}: refused: {result.reason or 'no reason given'}", flush=True)
        return 1
    print(f"{target} {args.name}: set", flush=True)
    return 0


def parameter_msg(name: str, text: str) -> Any:
    """``rcl_interfaces/Parameter`` of ``text`` read as YAML (a ConfigError naming the value if it has no ROS type)."""
    from rclpy.parameter import Parameter

    value = yaml.safe_load(text)
    try:
        return Parameter(name, value=value).to_parameter_msg()
    except TypeError as err:
        raise ConfigError(f"param set {name}: {text!r} is no ROS parameter value ({err})") from err


def _print_value(target: str, name: str, value: Any) -> int:
    from rcl_interfaces.msg import ParameterType
    from rclpy.parameter import parameter_value_to_python

    if value is None or value.type == ParameterType.PARAMETER_NOT_SET:
        print(f"{target} has no parameter {name} (or it is not set)", flush=True)
        return 1
    print(f"{name}: {parameter_value_to_python(value)!r}", flush=True)
    return 0


def describe_text(descriptor: Any) -> str:
    """A parameter descriptor as lines: name, type, description, read-only, ranges."""
    from rcl_interfaces.msg import ParameterType

    type_names = {getattr(ParameterType, n): n.removeprefix("PARAMETER_").lower()
                  for n in dir(ParameterType) if n.startswith("PARAMETER_")}
    lines = [f"parameter: {descriptor.name}", f"  type: {type_names.get(descriptor.type, descriptor.type)}",
             f"  description: {descriptor.description}", f"  read_only: {str(descriptor.read_only).lower()}"]
    if descriptor.additional_constraints:
        lines.append(f"  constraints: {descriptor.additional_constraints}")
    for kind, ranges in (("float", descriptor.floating_point_range), ("integer", descriptor.integer_range)):
        for r in ranges:
            lines.append(f"  {kind} range: [{r.from_value}, {r.to_value}]" + (f" step {r.step}" if r.step else ""))
    return "\n".join(lines)


def _call(node: Any, srv_type: type, name: str, request: Any, wait_s: float) -> Any:
    """Call service ``name`` once it is there; its answer (a ConfigError naming it after ``wait_s``)."""
    import rclpy

    client = node.create_client(srv_type, name)
    if not client.wait_for_service(timeout_sec=wait_s):
        raise ConfigError(f"no service {name} within --wait-s {wait_s} s (cnc-contour ros nodes lists the nodes)")
    future = client.call_async(request)
    deadline_s = time.monotonic() + wait_s
    while not future.done() and time.monotonic() < deadline_s:
        rclpy.spin_once(node, timeout_sec=0.05)
    if not future.done():
        raise ConfigError(f"{name} did not answer within --wait-s {wait_s} s")
    return future.result()


def lifecycle(node: Any, args: argparse.Namespace) -> int:
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState, GetState

    target = args.node if args.node.startswith("/") else f"/{args.node}"
    if args.verb == "set":
        if args.transition is None:
            raise ConfigError(f"lifecycle set needs a TRANSITION, one of {', '.join(TRANSITIONS)}")
        request = ChangeState.Request(transition=Transition(label=args.transition))
        if not _call(node, ChangeState, f"{target}/change_state", request, args.wait_s).success:
            print(f"{target} {args.transition}: refused (its log and /diagnostics give the reason)", flush=True)
            return 1
    state = _call(node, GetState, f"{target}/get_state", GetState.Request(), args.wait_s).current_state.label
    print(f"{target}: {state}", flush=True)
    return 0


#: The tools by subcommand (``action`` is cnc-contour send-program's, on its own node).
TOOLS: dict[str, Callable[[Any, argparse.Namespace], int]] = {
    "nodes": nodes, "topics": topics, "echo": echo, "hz": hz, "param": param, "lifecycle": lifecycle}
