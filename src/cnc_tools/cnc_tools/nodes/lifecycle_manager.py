"""Lifecycle manager node: drives managed nodes through configure, then activate, in a given order.

    lifecycle_manager --ros-args -r __ns:=/cnc -p node_names:="[interpolator, servo_x, servo_y, plant]"

Every node is configured before any is activated, each in ``node_names``'s
order (the plant last: it starts the clock once it is active). While a node's
``change_state`` service is not there, the manager says so (STALE on
``/diagnostics``, nodes/common.py); a refused transition, or one not answered
within ``transition_timeout_s``, is a fault naming the node and the
transition, and the manager exits 3. Once every node is active it reports OK
and stays up (a run's end is the plant's), so a supervisor sees one process
per role.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rclpy.parameter import Parameter

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.nodes.common import SuiteNode, describe, spin_node, wall_time_s

#: The transitions an autostart drives, in order, with their names as the log says them.
AUTOSTART = ((Transition.TRANSITION_CONFIGURE, "configure"), (Transition.TRANSITION_ACTIVATE, "activate"))
#: Each transition's start and goal state (labels of lifecycle_msgs/State).
STATES = {"configure": ("unconfigured", "inactive"), "activate": ("inactive", "active")}
#: An unanswered or refused request is checked against the node's state after this long: a response lost in
#: discovery (the server's answer writer not yet matched to this client) must not stall the start-up.
ANSWER_WAIT_S = 2.0


@dataclass
class TransitionPlan:
    """The steps (node, transition id, transition name) of an autostart and where it stands (ROS-free)."""

    node_names: tuple[str, ...]
    steps: list[tuple[str, int, str]] = field(init=False)
    done: int = 0

    def __post_init__(self) -> None:
        if not self.node_names or len(set(self.node_names)) != len(self.node_names):
            raise ConfigError(f"node_names must name each managed node once, got {list(self.node_names)}")
        self.steps = [(name, tid, label) for tid, label in AUTOSTART for name in self.node_names]

    @property
    def finished(self) -> bool:
        """True once every step succeeded."""
        return self.done == len(self.steps)

    @property
    def current(self) -> tuple[str, int, str]:
        """The step to take next."""
        return self.steps[self.done]


class LifecycleManagerNode(SuiteNode):
    """Configures, then activates, the nodes of ``node_names`` (relative to its namespace) one after the other."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("lifecycle_manager", **kwargs)
        names = self.declare("node_names", Parameter.Type.STRING_ARRAY, describe(
            "managed nodes, in the order to configure and then activate them (the plant last)", read_only=True))
        self.timeout_s = self.declare("transition_timeout_s", 30.0, describe(
            "wall time a transition may take once its service is there, s", 0.1, 600.0, True))
        self.startup_timeout_s = self.declare("startup_timeout_s", 90.0, describe(
            "wall time to wait for a node's change_state service, s", 0.1, 3600.0, True))
        self.plan = TransitionPlan(tuple(names or ()))
        self._change_state = {name: self.create_client(ChangeState, f"{name}/change_state")
                              for name in self.plan.node_names}
        self._get_state = {name: self.create_client(GetState, f"{name}/get_state") for name in self.plan.node_names}
        self._pending: Any = None
        self._state_query: Any = None
        self._sent_s = wall_time_s()
        self._since_s = wall_time_s()
        self._timer = self.create_timer(0.02, self.guarded(self._advance))

    def _advance(self) -> None:
        """Take the next step once its service is there; check the one under way."""
        if self._pending is not None:
            self._check_pending()
            return
        name, _, label = self.plan.current
        client = self._change_state[name]
        if not client.service_is_ready():
            self.waiting_for("service", f"{client.srv_name} to {label} {name}")
            if wall_time_s() - self._since_s > self.startup_timeout_s:
                self.fault(f"lifecycle_manager: no {client.srv_name} within {self.startup_timeout_s} s")
            return
        self.waiting_for("service", None)
        self._since_s = wall_time_s()
        self._send()

    def _send(self) -> None:
        name, transition_id, _ = self.plan.current
        self._sent_s = wall_time_s()
        request = ChangeState.Request(transition=Transition(id=transition_id))
        self._pending = self._change_state[name].call_async(request)

    def _check_pending(self) -> None:
        """An answer, or after ANSWER_WAIT_S without one (or with a refusal) the node's state, decides the step."""
        name, _, label = self.plan.current
        if self._state_query is not None:
            self._check_state()
        elif self._pending.done() and self._pending.result().success:
            self._step_done()
        elif self._pending.done() or wall_time_s() - self._sent_s > ANSWER_WAIT_S:
            self._state_query = self._get_state[name].call_async(GetState.Request())
        if self._pending is not None and wall_time_s() - self._since_s > self.timeout_s:
            self.fault(f"lifecycle_manager: {label} {name} not answered within {self.timeout_s} s")

    def _check_state(self) -> None:
        """The node's state after an unanswered or refused request: done, send again, or refused."""
        name, _, label = self.plan.current
        if not self._state_query.done():
            if wall_time_s() - self._sent_s > 2 * ANSWER_WAIT_S:
                self._state_query = None  # the query itself was lost: ask again
            return
        state = self._state_query.result().current_state.label
        self._state_query = None
        start, goal = STATES[label]
        if state == goal:
            self._step_done()
        elif self._pending.done():
            self.fault(f"lifecycle_manager: {label} {name} refused (see {name}'s log and /diagnostics)")
        elif state == start:
            self._send()  # the request was lost: send it again
        else:
            self._sent_s = wall_time_s()  # still in transition: look again in ANSWER_WAIT_S

    def _step_done(self) -> None:
        name, _, label = self.plan.current
        self.get_logger().info(f"{label} {name}: done")
        self._pending, self._since_s = None, wall_time_s()
        self.plan.done += 1
        if self.plan.finished:
            self._timer.cancel()
            self.report(DiagnosticStatus.OK, f"active: {', '.join(self.plan.node_names)}")


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_tools lifecycle_manager``."""
    raise SystemExit(spin_node(LifecycleManagerNode, args))
