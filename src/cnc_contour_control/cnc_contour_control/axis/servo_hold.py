"""A servo that stops integrating while its machine is off and resumes bumplessly (ROS-free).

While the e-stop latch (:class:`~cnc_contour_control.axis.safety.EstopLatch`) blocks
commands (latched, or the axis disabled) the drive gets zero, so a law that
kept integrating the growing following error would wind up and kick the axis
on enable. Here the law is not stepped at all while blocked: its state
(the PID's u(k−1), e(k−1), r(k−1); any observer's) is frozen, the command is
0 and the following-error trip is off (LinuxCNC checks it only while
enabled). On the first sample allowed again the law restarts from its reset
state (applied command 0: what the drive had) and the reference is re-based
on the current position::

    gap_m       = position_m − ref_position_m           at the first allowed sample, t_r
    s           = (t − t_r) / resume_ramp_s, clipped to [0, 1]
    offset_m    = gap_m · (1 − (3 s² − 2 s³))            smoothstep: 0 velocity at both ends
    law's ref   = ref + offset (position, velocity, acceleration: the offset's derivatives added)

so the law starts at zero error where the axis stands and the gap closes
smoothly over ``resume_ramp_s``; afterwards the servo is the plain
:class:`~cnc_contour_control.axis.servo.ServoController`, bit for bit. The
following-error trip sees the re-based error during the ramp.

The trip (:class:`~cnc_contour_control.axis.safety.FollowingErrorGuard`) is checked
after each allowed sample: with ``ferror_action`` ``fault`` it raises, as the
engine does; with ``latch`` it trips the latch, the sample's command is
already 0 (the drive is off from the tripping tick on) and the trip waits in
:meth:`HeldServo.take_trip` for the node to report it and e-stop the machine.
"""
from __future__ import annotations

from dataclasses import dataclass

from cnc_contour_control.axis.safety import EstopLatch, FerrorTrip, FollowingErrorGuard, limit_of
from cnc_contour_control.axis.servo import ServoController, ServoOutput
from cnc_contour_control.core.lockstep import NS_PER_S
from cnc_contour_control.core.params import check_ranges, param

__all__ = ["HeldServo", "HoldParams"]


@dataclass(frozen=True)
class HoldParams:
    """How a servo resumes after an e-stop or a disable (run parameters of the servo node)."""

    resume_ramp_s: float = param(0.5, unit="s", low=1.0e-3, high=60.0, read_only=True,
                                 description="after an e-stop reset and enable: time over which the reference "
                                             "moves from the axis's position back onto the path (smoothstep)")

    def __post_init__(self) -> None:
        check_ranges(self)


class HeldServo:
    """``controller`` gated by ``latch`` (see the module docstring).

    Parameters
    ----------
    controller : ServoController
        The axis's servo.
    latch : EstopLatch
        The machine's latch; commands flow while ``latch.commands_allowed``.
    params : HoldParams
        The resume ramp.
    ferror_action : str
        What a following-error trip does (:data:`~cnc_contour_control.axis.safety.FERROR_ACTIONS`).
    """

    def __init__(self, controller: ServoController, latch: EstopLatch, params: HoldParams | None = None,
                 ferror_action: str = "fault") -> None:
        self.controller, self.latch = controller, latch
        self.ramp_s = (params or HoldParams()).resume_ramp_s
        self.guard = FollowingErrorGuard(ferror_action, latch)
        self.held = False
        self.held_samples = 0
        self._gap_m = 0.0
        self._resumed_ns: int | None = None
        self._trip: FerrorTrip | None = None

    def step(self, stamp_ns: int, dt_s: float, ref_position_m: float, ref_velocity_m_s: float,
             ref_acceleration_m_s2: float, position_m: float, velocity_m_s: float,
             compensation: float) -> ServoOutput:
        """One sample at ``stamp_ns`` [ns] (arguments as :meth:`ServoController.step`): held, resuming or plain.

        Then the following-error trip on the sample's (re-based) error at ``ref_velocity_m_s``: with
        ``ferror_action`` ``fault`` a :class:`~cnc_contour_control.core.errors.FaultError`, with ``latch`` the latch
        trips and the sample is held (command 0).
        """
        if not self.latch.commands_allowed:
            return self._hold(ref_position_m, position_m)
        if self.held:
            self.held = False
            self.controller.reset()
            self._gap_m, self._resumed_ns = position_m - ref_position_m, int(stamp_ns)
        law_ref = (ref_position_m, ref_velocity_m_s, ref_acceleration_m_s2)
        if self._resumed_ns is not None:
            offset = self.offset(stamp_ns)
            law_ref = (ref_position_m + offset[0], ref_velocity_m_s + offset[1], ref_acceleration_m_s2 + offset[2])
        output = self.controller.step(dt_s, *law_ref, position_m, velocity_m_s, compensation)
        trip = self.guard.check(limit_of(self.controller.config), output.error_m, ref_velocity_m_s, stamp_ns)
        if trip is None:
            return output
        self._trip = trip
        return self._hold(ref_position_m, position_m)

    def _hold(self, ref_position_m: float, position_m: float) -> ServoOutput:
        """A held sample: command 0, the law not stepped."""
        self.held = True
        self.held_samples += 1
        return ServoOutput(0.0, 0.0, 0.0, 0.0, 0.0, False, ref_position_m - position_m)

    def take_trip(self) -> FerrorTrip | None:
        """Once per trip (``ferror_action`` ``latch``): the trip of the last sample; else None."""
        trip, self._trip = self._trip, None
        return trip

    @property
    def resuming(self) -> bool:
        """True while the reference is re-based (the ramp after a resume)."""
        return self._resumed_ns is not None

    def offset(self, stamp_ns: int) -> tuple[float, float, float]:
        """The reference's offset at ``stamp_ns``: [m], [m/s], [m/s²] (zeros once the ramp is over)."""
        if self._resumed_ns is None:
            return 0.0, 0.0, 0.0
        s = (int(stamp_ns) - self._resumed_ns) / NS_PER_S / self.ramp_s
        if s >= 1.0:
            self._resumed_ns = None
            return 0.0, 0.0, 0.0
        gap, ramp = self._gap_m, self.ramp_s
        return (gap * (1.0 - (3.0 * s * s - 2.0 * s * s * s)), -gap * 6.0 * s * (1.0 - s) / ramp,
                -gap * (6.0 - 12.0 * s) / (ramp * ramp))
