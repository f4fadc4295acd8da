"""The interpolator's ``~/home`` service (std_srvs/Trigger) and its homed state on ``/diagnostics``.

Only translation: :meth:`~cnc_contour_control.motion.program_session.ProgramSession.home`
decides (motion/homing.py). The service answers at once: ``success`` with
what the homing does, or false with why it cannot start (busy, inactive,
machine stopped). The homed state of every axis (``homed.<axis>``) is
reported when it changes and every :data:`HOMING_STATUS_PERIOD_S`, WARN while
``require_homing`` holds programs back.
"""
from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from std_srvs.srv import Trigger

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.motion.program_session import ProgramSession

#: The service's name: the interpolator's own, as ~/reset and ~/enable on plant and servos.
HOME_SERVICE = "~/home"
#: Wall time between two reports of the homed state, s.
HOMING_STATUS_PERIOD_S = 1.0


class HomingService:
    """``home`` on ``node`` for ``session``, and the homed state on /diagnostics."""

    def __init__(self, node: Any, session: ProgramSession) -> None:
        self.node, self.session = node, session
        self._reported: list[bool] | None = None
        self.service = node.create_service(Trigger, HOME_SERVICE, self._home)  # catches its errors (a reply)
        node.create_timer(HOMING_STATUS_PERIOD_S, node.guarded(self.report))

    def _home(self, request: Any, response: Any) -> Any:
        """Start homing, or say why not."""
        try:
            if not self.node.armed:
                raise CncError("the interpolator is not active (lifecycle): activate it first")
            response.message = self.session.home()
            response.success = True
        except CncError as err:
            response.success, response.message = False, f"home refused: {err}"
        self.node.get_logger().info(f"home: {response.message}")
        self.report()
        return response

    def after_tick(self) -> None:
        """After each tick: report the homed state once it changed."""
        if self._reported != self.session.homed.homed:
            self.report()

    def report(self) -> None:
        """The homed state of every axis on /diagnostics (WARN while programs wait for homing)."""
        state = self.session.homed
        self._reported = list(state.homed)
        waiting = state.required and not all(state.homed)
        unhomed = [a for a, h in zip(state.axes, state.homed) if not h]
        message = (f"not homed: {', '.join(unhomed)}" + ("; programs refused until homed" if waiting else "")
                   if unhomed else "every axis homed")
        self.node.report(DiagnosticStatus.WARN if waiting else DiagnosticStatus.OK, message, state.values())
