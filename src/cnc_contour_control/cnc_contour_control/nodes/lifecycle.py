"""Managed nodes: the ROS 2 lifecycle (``rclpy.lifecycle``) over a node's configure / activate / deactivate hooks.

A node of the suite that overrides :meth:`ManagedNode.configure` (the
interpolator, the servos, the plant) is a managed node:

- ``managed: false`` (the default) -- it configures and activates itself when
  it is made, as a plain node did: a bad parameter is an error at start-up.
- ``managed: true`` -- it waits *unconfigured*, with nothing declared but
  ``managed``, until a lifecycle manager (the runner, ``ros2 lifecycle set``,
  a shop-floor lifecycle manager) drives it: **configure** declares and
  validates the parameters and builds the node (a refusal is FAILURE, logged
  and reported ERROR on ``/diagnostics`` with the reason; the node stays
  unconfigured); **activate** arms it; **deactivate** stops motion cleanly
  (each node says how, :meth:`ManagedNode.deactivate`); **shutdown** ends the
  process. **cleanup** is refused (the parameters are read-only once
  declared: restart the node to configure it anew).

A transition the state machine does not allow from the current state (e.g.
activate while unconfigured) is refused: the service answers
``success: false`` and the node keeps its state.
"""
from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn

from cnc_contour_control.core.errors import CncError

SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


class ManagedNode(LifecycleNode):  # type: ignore[misc]  # rclpy is skipped (mypy.ini): LifecycleNode is Any
    """A lifecycle node whose subclasses build themselves in :meth:`configure` (see the module docstring)."""

    def __init__(self, name: str, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.armed = False
        self.configure_error: CncError | None = None
        self.managed = self.is_lifecycle_managed() and bool(self.declare_parameter(
            "managed", False, ParameterDescriptor(
                description="wait unconfigured for a lifecycle manager (true) or configure and activate at once",
                read_only=True)).value)

    def is_lifecycle_managed(self) -> bool:
        """True for a node class that builds itself in :meth:`configure`."""
        return type(self).configure is not ManagedNode.configure

    def start_lifecycle(self) -> None:
        """Unmanaged: configure and activate now (a refused configure raises its error); managed: wait."""
        if self.managed:
            self.get_logger().info("managed: waiting unconfigured for configure")
            return
        if self.trigger_configure() != SUCCESS:
            raise self.configure_error or CncError(f"{self.get_name()}: configure failed")
        self.trigger_activate()

    # -- the hooks of a node ------------------------------------------------------------------------------------

    def configure(self) -> None:
        """Declare and validate the parameters, create the topics (a node that overrides this is managed)."""

    def activate(self) -> None:
        """Arm the node (default: nothing beyond ``armed``); raise CncError to refuse."""

    def deactivate(self) -> None:
        """Stop motion cleanly (default: nothing beyond ``armed``); raise CncError to refuse."""

    def report_status(self, level: bytes, message: str) -> None:
        """Publish a status on /diagnostics (SuiteNode's ``report``)."""
        raise NotImplementedError

    # -- the state machine's callbacks ------------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        try:
            self.configure()
        except CncError as err:
            self.configure_error = err
            return self._refuse("configure", err)
        return SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.armed = True
        try:
            self.activate()
        except CncError as err:
            self.armed = False
            return self._refuse("activate", err)
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        try:
            self.deactivate()
        except CncError as err:
            return self._refuse("deactivate", err)
        self.armed = False
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        return self._refuse("cleanup", CncError("its parameters are read-only once declared: restart the node "
                                                "to configure it anew"))

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.armed = False
        self.end_lifecycle()
        return SUCCESS

    def end_lifecycle(self) -> None:
        """Shutdown: the node's spin loop ends (SuiteNode sets ``finished``)."""

    def _refuse(self, transition: str, err: CncError) -> TransitionCallbackReturn:
        message = f"{transition} refused: {err}"
        self.get_logger().error(message)
        self.report_status(DiagnosticStatus.ERROR, message)
        return FAILURE

    def _LifecycleNodeMixin__on_change_state(self, request: Any, response: Any) -> Any:
        """The ``~/change_state`` service: a transition the state machine does not allow is refused, not raised.

        (rclpy raises out of the service callback, which would end the node's spin; the label form already
        answers ``success: false``.)
        """
        allowed = {description[0] for description in self._state_machine.available_transitions}
        if not request.transition.label and request.transition.id not in allowed:
            self.get_logger().warning(f"transition {request.transition.id} refused in state "
                                      f"{self._state_machine.current_state[1]!r}")
            response.success = False
            return response
        return super()._LifecycleNodeMixin__on_change_state(request, response)
