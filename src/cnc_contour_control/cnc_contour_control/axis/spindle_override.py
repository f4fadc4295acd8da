"""A spindle override at run time: the speed a node's ``spindle_rpm`` parameter commands (ROS-free).

A live ``spindle_rpm`` (``ros2 param set /cnc/servo spindle_rpm 1650``) is
handed to whatever follows the spindle on that node: the servo's law (paper
002's PDC and the PDC stacks redesign H for the new f_d,
:class:`~cnc_contour_control.laws.base.SpindleFollowing`) or the plant's
periodic disturbance (:func:`cnc_plant_sim.models.periodic_load.set_spindle_rpm`:
the new speed from the plant's present time on, phase continuous). A speed
that cannot be followed (f_d at or above Nyquist, a design that fails) is
refused with the receiver's :class:`ConfigError` as the reason and nothing
changes: the last valid speed and design stay. 0 ends the override (nothing
is redesigned then; the configured speed or schedule rules again at the next
retune or schedule change). The override outlives a retune: after
new gains (whose ``spindle_rpm`` is the design speed) :meth:`SpindleOverride.
reapply` gives the law the overridden speed again.
"""
from __future__ import annotations

import math
from collections.abc import Callable

from cnc_contour_control.core.errors import ConfigError

#: Range of the ``spindle_rpm`` parameter [rpm] (0: no override).
SPINDLE_RPM_RANGE = (0.0, 1.0e6)
#: The parameter's name and description (one declaration for every node that has it).
SPINDLE_RPM_PARAMETER = "spindle_rpm"
SPINDLE_RPM_DESCRIPTION = ("spindle speed commanded at run time [rpm] (f_d = rpm * flutes / 60; 0: no override); "
                           "a speed that cannot be followed is refused and reported on /diagnostics")


class SpindleOverride:
    """The overriding spindle speed and the receiver it goes to.

    Parameters
    ----------
    receiver : callable
        ``rpm -> anything``; raises :class:`ConfigError` to refuse a speed (changing nothing).

    Attributes
    ----------
    rpm : float or None
        The speed in force [rpm] (None: no override).
    """

    def __init__(self, receiver: Callable[[float], object]) -> None:
        self.receiver = receiver
        self.rpm: float | None = None

    def set(self, rpm: float) -> str | None:
        """Override with ``rpm`` [rpm] (0: end the override); the refusal's reason, else None."""
        if isinstance(rpm, bool) or not isinstance(rpm, (int, float)) or not math.isfinite(rpm) \
                or not SPINDLE_RPM_RANGE[0] <= rpm <= SPINDLE_RPM_RANGE[1]:
            return (f"{SPINDLE_RPM_PARAMETER} must be in [{SPINDLE_RPM_RANGE[0]:g}, {SPINDLE_RPM_RANGE[1]:g}], "
                    f"got {rpm!r}")
        if rpm == 0.0:
            self.rpm = None
            return None
        try:
            self.receiver(float(rpm))
        except ConfigError as err:
            kept = "the configured speed" if self.rpm is None else f"{self.rpm:g} rpm"
            return f"{SPINDLE_RPM_PARAMETER} {rpm:g} refused, keeping {kept}: {err}"
        self.rpm = float(rpm)
        return None

    def reapply(self) -> str | None:
        """Give the receiver the overriding speed again (after a retune); the refusal's reason, else None."""
        if self.rpm is None:
            return None
        try:
            self.receiver(self.rpm)
        except ConfigError as err:
            return f"{SPINDLE_RPM_PARAMETER} {self.rpm:g} no longer followed after the retune: {err}"
        return None


def law_receiver(law: object) -> Callable[[float], object]:
    """The receiver of a servo's law: its ``set_spindle_rpm`` if it follows the spindle, else a no-op."""
    follow = getattr(law, "set_spindle_rpm", None)
    return follow if callable(follow) else (lambda rpm: False)
