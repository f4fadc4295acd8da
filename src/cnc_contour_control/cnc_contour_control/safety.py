"""Machine safety: the following-error trip and the e-stop latch (ROS-free).

Following-error trip (LinuxCNC's FERROR / MIN_FERROR), per axis and sample::

    bound_m = min_ferror_m + ferror_m · |v_ref| / ferror_velocity_m_s
    trip    when |error_m| > bound_m

``ferror_m`` is the bound added at ``ferror_velocity_m_s`` (the axis's
maximum velocity, LinuxCNC's MAX_VELOCITY); ``min_ferror_m`` the bound at
rest. Both 0 (the default) switch the trip off. The servo node and the
engine's servo stage call :func:`check_following_error` on every sample, so
both trip on the same tick with the same message.

E-stop latch (LinuxCNC's ``estop_latch``): an e-stop input that goes true
latches; while latched or disabled the plant applies zero commands. The latch
clears only on a reset while the input is false; enabling while latched is
refused with the cause. After a reset the machine is off until enabled again.
A fault (LinuxCNC's ``fault_in``: a partner node lost) latches the same way
without setting the input (:meth:`EstopLatch.trip`).

Lost partners: a node waiting for a lockstep input watches the input's
publishers in the ROS graph (:class:`PartnerWatch`). A topic that had
publishers and has none while a tick waits for it will never complete the
tick: the node stops the machine and faults naming the nodes that left.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from cnc_contour_control.errors import FaultError
from cnc_contour_control.lockstep import NS_PER_S

__all__ = ["EstopLatch", "FollowingErrorLimit", "LatchAnswer", "PartnerWatch", "check_following_error", "limit_of"]


class FerrorFields(Protocol):
    """What a servo config declares for the trip (:class:`~cnc_contour_control.servo.ServoConfig`)."""

    axis_name: str
    min_ferror_m: float
    ferror_m: float
    ferror_velocity_m_s: float


@dataclass(frozen=True)
class FollowingErrorLimit:
    """One axis's following-error bound (fields as :class:`~cnc_contour_control.servo.ServoConfig` declares them).

    Parameters
    ----------
    axis_name : str
        The axis, named in the fault.
    min_ferror_m : float
        Bound at rest [m] (LinuxCNC MIN_FERROR).
    ferror_m : float
        Bound added at ``ferror_velocity_m_s`` [m] (LinuxCNC FERROR).
    ferror_velocity_m_s : float
        Velocity at which ``ferror_m`` is reached [m/s] (> 0).
    """

    axis_name: str
    min_ferror_m: float = 0.0
    ferror_m: float = 0.0
    ferror_velocity_m_s: float = 1.0

    @property
    def active(self) -> bool:
        """True when the trip is on (either bound > 0)."""
        return self.min_ferror_m > 0.0 or self.ferror_m > 0.0

    def bound_m(self, velocity_m_s: float) -> float:
        """The allowed |following error| [m] at the reference velocity ``velocity_m_s`` [m/s]."""
        return self.min_ferror_m + self.ferror_m * abs(velocity_m_s) / self.ferror_velocity_m_s

    def tripped(self, error_m: float, velocity_m_s: float) -> bool:
        """True when the trip is on and ``|error_m|`` exceeds :meth:`bound_m`."""
        return self.active and abs(error_m) > self.bound_m(velocity_m_s)

    def message(self, error_m: float, velocity_m_s: float, stamp_ns: int) -> str:
        """The fault: axis, error, bound and its parts, tick stamp."""
        return (f"servo {self.axis_name}: following error {error_m:.9g} m exceeds the bound "
                f"{self.bound_m(velocity_m_s):.9g} m (min_ferror_m {self.min_ferror_m:g} + ferror_m "
                f"{self.ferror_m:g} * |v_ref| {abs(velocity_m_s):.6g} m/s / ferror_velocity_m_s "
                f"{self.ferror_velocity_m_s:g}) at t={stamp_ns / NS_PER_S:.6f} s")


def limit_of(config: FerrorFields) -> FollowingErrorLimit:
    """The trip of a servo config (its ``min_ferror_m``, ``ferror_m``, ``ferror_velocity_m_s``)."""
    return FollowingErrorLimit(config.axis_name, float(config.min_ferror_m), float(config.ferror_m),
                               float(config.ferror_velocity_m_s))


def check_following_error(limit: FollowingErrorLimit, error_m: float, velocity_m_s: float, stamp_ns: int) -> None:
    """Raise :class:`FaultError` (:meth:`FollowingErrorLimit.message`) when ``limit`` trips."""
    if limit.tripped(error_m, velocity_m_s):
        raise FaultError(limit.message(error_m, velocity_m_s, stamp_ns))


@dataclass(frozen=True)
class LatchAnswer:
    """The answer to an enable or reset request: accepted or not, and why (the service's message)."""

    accepted: bool
    message: str


class EstopLatch:
    """E-stop latch and machine enable of one machine (see the module docstring).

    Parameters
    ----------
    enabled : bool
        Whether the machine starts enabled (a run starts enabled).
    """

    def __init__(self, enabled: bool = True) -> None:
        self._initially_enabled = enabled
        self.reset_state()

    def reset_state(self) -> None:
        """Back to the start: not latched, input false, enabled as at construction."""
        self.enabled = self._initially_enabled
        self.latched = False
        self.estop_input = False
        self.cause = ""
        self.latch_count = 0

    @property
    def commands_allowed(self) -> bool:
        """True when commands reach the drives (enabled and not latched)."""
        return self.enabled and not self.latched

    def estop(self, active: bool, cause: str) -> bool:
        """Set the e-stop input; a true input latches (naming ``cause``). True if the latch was newly set."""
        self.estop_input = bool(active)
        if not active or self.latched:
            return False
        self.latched, self.cause = True, cause
        self.latch_count += 1
        return True

    def trip(self, cause: str) -> bool:
        """Latch on a fault (``cause``), leaving the e-stop input as it is. True if the latch was newly set."""
        if self.latched:
            return False
        self.latched, self.cause = True, cause
        self.latch_count += 1
        return True

    def reset(self) -> LatchAnswer:
        """Clear the latch, refused while the e-stop input is still true; the machine stays off until enabled."""
        if self.estop_input:
            return LatchAnswer(False, f"reset refused: the e-stop input is still true ({self.cause})")
        if not self.latched:
            return LatchAnswer(True, "not latched: nothing to reset")
        self.latched, self.enabled = False, False
        cause, self.cause = self.cause, ""
        return LatchAnswer(True, f"latch cleared ({cause}); the machine is off until enabled")

    def enable(self, on: bool) -> LatchAnswer:
        """Switch the machine on or off; on is refused while latched, with the cause."""
        if on and self.latched:
            return LatchAnswer(False, f"enable refused: e-stop latched ({self.cause}); reset first")
        self.enabled = bool(on)
        return LatchAnswer(True, "enabled" if on else "disabled")

    def gate(self, commands: Sequence[float]) -> list[float]:
        """``commands`` when allowed, else zeros of the same length (the drives are off)."""
        return list(commands) if self.commands_allowed else [0.0] * len(commands)

    def state(self) -> dict[str, str]:
        """The latch's state as diagnostic key/values."""
        return {"enabled": str(self.enabled).lower(), "estop_latched": str(self.latched).lower(),
                "estop_input": str(self.estop_input).lower(), "estop_cause": self.cause,
                "estop_latches": str(self.latch_count)}


class PartnerWatch:
    """The publishers of the topics a node waits for; a topic whose publishers all left is a lost partner.

    Parameters
    ----------
    topics : sequence of str
        The watched topics (resolved names, as the node subscribes them).
    """

    def __init__(self, topics: Sequence[str]) -> None:
        self.topics = tuple(topics)
        self._seen: dict[str, tuple[str, ...]] = {topic: () for topic in self.topics}

    def publishers(self, topic: str) -> tuple[str, ...]:
        """The publishing nodes of ``topic`` last seen (empty before any)."""
        return self._seen[topic]

    def observe(self, topic: str, nodes: Sequence[str | None], stamp_ns: int) -> str | None:
        """Note ``topic``'s publishing ``nodes`` now; the loss (a message) when all that published are gone.

        A node the graph does not name yet (None: discovery has its endpoint, not its name) keeps the
        names known before, else is noted as ``an unnamed node``.
        """
        if nodes:
            named = tuple(sorted({node for node in nodes if node}))
            self._seen[topic] = named or self._seen[topic] or ("an unnamed node",)
            return None
        lost = self._seen[topic]
        if not lost:
            return None
        return (f"{', '.join(lost)} left the graph: {topic} has 0 publishers (had {len(lost)}) "
                f"at t={stamp_ns / NS_PER_S:.6f} s")
