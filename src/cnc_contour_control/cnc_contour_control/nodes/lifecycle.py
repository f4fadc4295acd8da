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
  (each node says how, :meth:`ManagedNode.deactivate`); **cleanup** (from
  inactive) returns it to unconfigured: everything configure made (topics,
  timers, services, the action server, parameter callbacks) is destroyed, and
  the parameters configure declared stay, now writable (``ros2 param set``,
  ``cnc-contour ros param set``), so the next **configure** declares them
  read-only again with the new values and validates them as the first did;
  **shutdown** destroys what configure made (its topics leave the graph at
  once: a partner waiting for them faults naming the node, the plant stops
  the machine) and ends the process. In a composed process (a local bus) cleanup
  is refused: the bus's deliveries to the node cannot be taken back.

A transition the state machine does not allow from the current state (e.g.
activate while unconfigured) is refused: the service answers
``success: false`` and the node keeps its state.
"""
from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.nodes import local_bus

SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


class ManagedNode(LifecycleNode):  # type: ignore[misc]  # rclpy is skipped (mypy.ini): LifecycleNode is Any
    """A lifecycle node whose subclasses build themselves in :meth:`configure` (see the module docstring)."""

    def __init__(self, name: str, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.armed = False
        self.configure_error: CncError | None = None
        self._made_before: dict[str, int] = {}  # rclpy's entity lists' lengths before configure (cleanup's mark)
        self._writable: set[str] = set()  # parameters a cleanup left declared and writable until configure
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

    def cleanup(self) -> None:
        """Before configure's entities are destroyed: let go of anything else (default: nothing); CncError
        refuses."""

    def report_status(self, level: bytes, message: str) -> None:
        """Publish a status on /diagnostics (SuiteNode's ``report``)."""
        raise NotImplementedError

    # -- the state machine's callbacks ------------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._made_before = {kind: len(list(getattr(self, kind))) for kind in _ENTITY_LISTS}
        self._made_before["parameters"] = len(self._parameters)
        self._made_before.update({kind: len(getattr(self, f"_{kind}_callbacks")) for kind in _CALLBACK_LISTS})
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
        try:
            if local_bus.bus_of(self.context) is not None:
                raise CncError("the node runs in a composed process (a local bus): restart it to configure it anew")
            self.cleanup()
        except CncError as err:
            return self._refuse("cleanup", err)
        self._destroy_configured()
        self.configure_error = None
        self.get_logger().info(f"cleaned up: unconfigured, parameters writable until configure: "
                               f"{', '.join(sorted(self._writable)) or 'none'}")
        return SUCCESS

    def _destroy_configured(self) -> None:
        """Destroy what configure made (rclpy's entity lists grow at their ends); its parameters made writable."""
        for kind, destroy in _ENTITY_LISTS.items():
            made = list(getattr(self, kind))[self._made_before.get(kind, 0):]
            for entity in reversed(made):
                if kind == "waitables":
                    entity.destroy()  # an action server removes itself from the node
                else:
                    getattr(self, destroy)(entity)
        for kind in _CALLBACK_LISTS:
            del getattr(self, f"_{kind}_callbacks")[self._made_before.get(kind, 0):]
        for name in list(self._parameters)[self._made_before.get("parameters", 0):]:
            descriptor = self._descriptors[name]
            self._descriptors[name] = type(descriptor)(**{**_fields(descriptor), "read_only": False})
            self._writable.add(name)

    def declare_parameter(self, name: str, value: Any = None, descriptor: ParameterDescriptor | None = None,
                          ignore_override: bool = False) -> Parameter:
        """rclpy's; a parameter a cleanup left writable is declared anew with its value as set since."""
        if name in getattr(self, "_writable", ()):  # rclpy declares use_sim_time before __init__ sets it
            self._writable.discard(name)
            self._parameter_overrides[name] = self._parameters.pop(name)
            del self._descriptors[name]
        return super().declare_parameter(name, value, descriptor, ignore_override)

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """End the node; what configure made leaves the graph now (not when the process ends), so a partner
        that waited for it faults naming it at once while the others stay up."""
        self.armed = False
        if state.label != "unconfigured" and local_bus.bus_of(self.context) is None:
            self._destroy_configured()
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


#: rclpy's entity lists (Node properties) and the method that destroys one of each (waitables destroy themselves).
_ENTITY_LISTS = {"publishers": "destroy_publisher", "subscriptions": "destroy_subscription",
                 "clients": "destroy_client", "services": "destroy_service", "timers": "destroy_timer",
                 "guards": "destroy_guard_condition", "waitables": ""}
#: rclpy's parameter callback lists (``_<kind>_callbacks``), cut back to their length before configure on cleanup.
_CALLBACK_LISTS = ("pre_set_parameters", "on_set_parameters", "post_set_parameters")


def _fields(descriptor: ParameterDescriptor) -> dict[str, Any]:
    """A ParameterDescriptor's fields by name."""
    return {name: getattr(descriptor, name) for name in descriptor.get_fields_and_field_types()}
