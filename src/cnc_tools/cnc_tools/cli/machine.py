"""``cnc-contour machine ACTION``: the operator's panel of a running graph: e-stop, release, reset, enable, disable,
home.

``estop`` / ``release`` publish true / false on ``<namespace>/estop``
(std_msgs/Bool), once every reader the graph shows has matched. ``reset``,
``enable`` and ``disable`` call ``~/reset`` (std_srvs/Trigger) or ``~/enable``
(std_srvs/SetBool) on every node of the namespace that offers it (the plant
and the servos; design.md §3 Safety) and print each answer. A fresh node sees
the graph bit by bit, so ``--nodes plant servo_x servo_y`` names the nodes to
wait for; without it, the ones the graph shows once it settled. ``home`` calls
the interpolator's ``~/home`` (std_srvs/Trigger; action mode, design.md §4):
the axes go to the home position one at a time. Exit code 0 when
every answer was a success, 1 when one was refused (the reason is printed),
3 when nothing answered.
"""
from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.errors import ConfigError


@dataclass(frozen=True)
class PanelAction:
    """One button: the e-stop topic's value, or a service (suffix, type name) and its request's ``data``."""

    help: str
    estop: bool | None = None
    service: str = ""
    data: bool | None = None


#: The panel's buttons by name.
ACTIONS: dict[str, PanelAction] = {
    "estop": PanelAction("e-stop: every node latches, commands go to zero", estop=True),
    "release": PanelAction("release the e-stop (the latches stay until reset)", estop=False),
    "reset": PanelAction("~/reset on every node: clear the latch once the e-stop is released", service="reset"),
    "enable": PanelAction("~/enable true on every node (refused while latched, naming the cause)",
                          service="enable", data=True),
    "disable": PanelAction("~/enable false on every node: zero commands", service="enable", data=False),
    "home": PanelAction("~/home on the interpolator: the axes to the home position, then homed", service="home"),
}
#: Wall time to wait for the readers' acknowledgement of one e-stop message before it is sent again, s.
ACK_WAIT_S = 0.5
#: Wall time the list of services must stay the same before it is taken as complete, s.
DISCOVERY_SETTLE_S = 1.0
#: Service suffix -> its type as the ROS graph names it.
SERVICE_TYPES = {"reset": "std_srvs/srv/Trigger", "enable": "std_srvs/srv/SetBool", "home": "std_srvs/srv/Trigger"}


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=sorted(ACTIONS),
                        help="; ".join(f"{name}: {action.help}" for name, action in ACTIONS.items()))
    parser.add_argument("--namespace", default="/cnc", help="the graph's namespace (default /cnc)")
    parser.add_argument("--nodes", nargs="+", default=[], metavar="NODE",
                        help="the nodes to address, relative to the namespace (default: those the graph shows)")
    parser.add_argument("--wait-s", type=float, default=10.0, help="wall time to find the nodes (default 10)")


def machine(args: argparse.Namespace) -> int:
    """Press the button ``args.action``; the exit code of the answers."""
    import rclpy

    action = ACTIONS[args.action]
    rclpy.init()
    node = rclpy.create_node("machine_panel")
    try:
        if action.estop is not None:
            return publish_estop(node, f"{args.namespace.rstrip('/')}/estop", action.estop, args.wait_s,
                                 len(args.nodes))
        return call_all(node, args.namespace, action, args.wait_s, args.nodes)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def _spin_until(node: Any, condition: Callable[[], bool], timeout_s: float) -> bool:
    import rclpy

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        rclpy.spin_once(node, timeout_sec=0.05)
    return condition()


def publish_estop(node: Any, topic: str, value: bool, wait_s: float, min_readers: int = 0) -> int:
    """Publish ``value`` on ``topic`` once every reader in the graph (at least ``min_readers``) matched; until acked."""
    from rclpy.duration import Duration
    from std_msgs.msg import Bool

    publisher = node.create_publisher(Bool, topic, 10)
    def readers() -> int:
        return max(min_readers, int(node.count_subscribers(topic)))

    if not _spin_until(node, lambda: readers() > 0 and publisher.get_subscription_count() >= readers(), wait_s):
        raise ConfigError(f"no reader of {topic} within --wait-s {wait_s} s (is the graph running, in this domain?)")
    deadline = time.monotonic() + wait_s
    while True:  # a level, so repeating it is harmless: until every reader acknowledged it (a reader that has not
        publisher.publish(Bool(data=value))  # matched this writer yet drops what came before)
        if publisher.wait_for_all_acked(Duration(seconds=ACK_WAIT_S)):
            break
        if time.monotonic() > deadline:
            raise ConfigError(f"{topic}: not every reader acknowledged {str(value).lower()} within {wait_s} s")
    print(f"{topic}: {str(value).lower()} ({publisher.get_subscription_count()} readers)", flush=True)
    return 0


def panel_services(node: Any, namespace: str, suffix: str) -> list[str]:
    """The ``<namespace>/<node>/<suffix>`` services of the right type the graph shows now, sorted."""
    prefix = namespace.rstrip("/") + "/"
    depth = prefix.count("/") + 1  # <namespace>/<node>/<suffix>: a node of the namespace itself

    def ours(name: str, types: list[str]) -> bool:
        return name.startswith(prefix) and name.endswith(f"/{suffix}") and name.count("/") == depth \
            and SERVICE_TYPES[suffix] in types

    return sorted(name for name, types in node.get_service_names_and_types() if ours(name, types))


def latch_holders(node: Any, namespace: str) -> set[str]:
    """The nodes that read ``<namespace>/estop`` (each holds a latch), as the graph shows them now."""
    topic = namespace.rstrip("/") + "/estop"
    return {f"{info.node_namespace.rstrip('/')}/{info.node_name}"
            for info in node.get_subscriptions_info_by_topic(topic)}


def _discover(node: Any, namespace: str, suffix: str, wait_s: float) -> list[str]:
    """The services, once every latch holder the graph shows offers one and the list stayed the same for a while.

    A fresh node sees the graph bit by bit (discovery): a node's e-stop reader may show before its services.
    """
    found: list[list[str]] = [[]]
    stable_since = [time.monotonic()]

    def settled() -> bool:
        names = panel_services(node, namespace, suffix)
        if names != found[0]:
            found[0], stable_since[0] = names, time.monotonic()
        offered = {name.rsplit("/", 1)[0] for name in names}
        holders = latch_holders(node, namespace) if suffix != "home" else set()  # home: the interpolator's alone
        return (bool(names) and holders <= offered
                and time.monotonic() - stable_since[0] >= DISCOVERY_SETTLE_S)

    _spin_until(node, settled, wait_s)
    return found[0]


def call_all(node: Any, namespace: str, action: PanelAction, wait_s: float, nodes: list[str] | None = None) -> int:
    """Call the action's service on each of ``nodes`` (default: every node that offers it); print each answer."""
    from std_srvs.srv import SetBool, Trigger

    prefix = namespace.rstrip("/")
    names = ([f"{prefix}/{name.strip('/')}/{action.service}" for name in nodes] if nodes
             else _discover(node, namespace, action.service, wait_s))
    if not names:
        print(f"no {namespace}/*/{action.service} service within --wait-s {wait_s} s", flush=True)
        return 3
    srv_type = SetBool if action.data is not None else Trigger
    refused = 0
    for name in names:
        client = node.create_client(srv_type, name)
        request = srv_type.Request() if action.data is None else srv_type.Request(data=action.data)
        future = client.call_async(request) if client.wait_for_service(timeout_sec=wait_s) else None
        if future is None or not _spin_until(node, future.done, wait_s):
            print(f"{name}: no answer within {wait_s} s", flush=True)
            refused += 1
            continue
        answer = future.result()
        refused += not answer.success
        print(f"{name}: {'ok' if answer.success else 'REFUSED'}: {answer.message}", flush=True)
    return 1 if refused else 0
