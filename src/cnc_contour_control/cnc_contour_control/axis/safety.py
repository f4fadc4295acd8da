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

What a trip does (``ferror_action``, :class:`FollowingErrorGuard`): ``fault``
(the default, and the runner's and the engine's) raises the
:class:`FaultError`, the servo faults and exits. ``latch`` is LinuxCNC's "a
following error turns the machine off": the servo's own latch trips with the
cause (axis, error, bound, tick), the servo e-stops the machine (the e-stop
input true, then false: the cause is gone once the axis stands, so a reset is
allowed) and stays up; reset and enable resume it.

The machine as a program sees it (:class:`MachineWatch`): the plant and the
servos report their latch on ``/diagnostics`` (``enabled``,
``estop_latched``, ``estop_cause``); the machine runs while none of them
blocks, and the first one that blocks names the cause.

Lost partners: a node waiting for a lockstep input watches the input's
publishers in the ROS graph (:class:`PartnerWatch`). A topic that had
publishers and has none while a tick waits for it will never complete the
tick: the node stops the machine and faults naming the nodes that left.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

from cnc_contour_control.core.config import require_choice
from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.core.lockstep import NS_PER_S
from cnc_contour_control.core.params import check_ranges, param

__all__ = ["EstopLatch", "FERROR_ACTIONS", "FerrorActionParams", "FerrorTrip", "FollowingErrorGuard",
           "FollowingErrorLimit", "LatchAnswer", "MachineWatch", "PartnerWatch", "check_following_error",
           "following_error_trip", "limit_of"]


class FerrorFields(Protocol):
    """What a servo config declares for the trip (:class:`~cnc_contour_control.axis.servo.ServoConfig`)."""

    # read-only properties: a frozen dataclass's fields satisfy them
    @property
    def axis_name(self) -> str: ...
    @property
    def min_ferror_m(self) -> float: ...
    @property
    def ferror_m(self) -> float: ...
    @property
    def ferror_velocity_m_s(self) -> float: ...


@dataclass(frozen=True)
class FollowingErrorLimit:
    """One axis's following-error bound (fields as :class:`~cnc_contour_control.axis.servo.ServoConfig` declares them).

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


@dataclass(frozen=True)
class FerrorTrip:
    """One following-error trip: the axis, the error and the bound [m], the tick's stamp [ns] and the message."""

    axis_name: str
    error_m: float
    bound_m: float
    stamp_ns: int
    message: str

    def values(self) -> dict[str, str]:
        """The trip as diagnostic key/values."""
        return {"axis": self.axis_name, "following_error_m": f"{self.error_m:.9g}",
                "ferror_bound_m": f"{self.bound_m:.9g}", "stamp_ns": str(self.stamp_ns)}


def following_error_trip(limit: FollowingErrorLimit, error_m: float, velocity_m_s: float,
                         stamp_ns: int) -> FerrorTrip | None:
    """The trip when ``limit`` trips on ``error_m`` [m] at the reference velocity ``velocity_m_s`` [m/s]; else None."""
    if not limit.tripped(error_m, velocity_m_s):
        return None
    return FerrorTrip(limit.axis_name, float(error_m), limit.bound_m(velocity_m_s), int(stamp_ns),
                      limit.message(error_m, velocity_m_s, stamp_ns))


def check_following_error(limit: FollowingErrorLimit, error_m: float, velocity_m_s: float, stamp_ns: int) -> None:
    """Raise :class:`FaultError` (:meth:`FollowingErrorLimit.message`) when ``limit`` trips."""
    trip = following_error_trip(limit, error_m, velocity_m_s, stamp_ns)
    if trip is not None:
        raise FaultError(trip.message)


#: What a following-error trip does: ``fault`` the servo faults and exits; ``latch`` it latches and e-stops the
#: machine, which a reset and an enable resume (see the module docstring).
FERROR_ACTIONS = ("fault", "latch")


@dataclass(frozen=True)
class FerrorActionParams:
    """What a servo node does on a following-error trip (a run parameter of the servo node).

    Parameters
    ----------
    ferror_action : str
        One of :data:`FERROR_ACTIONS`.
    """

    ferror_action: str = param("fault", read_only=True,
                               description="on a following-error trip: fault (the servo faults and exits) or "
                                           "latch (the servo latches and e-stops the machine; reset and enable "
                                           "resume it)")

    def __post_init__(self) -> None:
        require_choice("ferror_action", self.ferror_action, FERROR_ACTIONS)
        check_ranges(self)


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
    confirm : int
        Observations in a row with no publisher before a topic counts as lost (>= 1): one graph query under a
        starved CPU once read 0 publishers of a live servo in process (a false "left the graph"); two in a row,
        0.25 s apart in the nodes, still find an exiting node well within a second.
    """

    def __init__(self, topics: Sequence[str], confirm: int = 2) -> None:
        self.topics = tuple(topics)
        self.confirm = max(1, int(confirm))
        self._seen: dict[str, tuple[str, ...]] = dict.fromkeys(self.topics, ())
        self._missing: dict[str, int] = dict.fromkeys(self.topics, 0)

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
            self._missing[topic] = 0
            return None
        lost = self._seen[topic]
        if not lost:
            return None
        self._missing[topic] += 1
        if self._missing[topic] < self.confirm:
            return None
        return (f"{', '.join(lost)} left the graph: {topic} has 0 publishers (had {len(lost)}) "
                f"at t={stamp_ns / NS_PER_S:.6f} s")


def _raise_fault(latch: EstopLatch, trip: FerrorTrip) -> None:
    raise FaultError(trip.message)


def _latch_machine(latch: EstopLatch, trip: FerrorTrip) -> None:
    latch.trip(trip.message)


#: ``ferror_action`` -> what a trip does to the servo's latch (or raises).
_FERROR_RESPONSES: dict[str, Callable[[EstopLatch, FerrorTrip], None]] = {
    "fault": _raise_fault,
    "latch": _latch_machine,
}


class FollowingErrorGuard:
    """A servo's following-error trip and what it does (``action``, one of :data:`FERROR_ACTIONS`).

    Parameters
    ----------
    action : str
        ``fault``: :meth:`check` raises the :class:`FaultError`. ``latch``:
        :meth:`check` trips ``latch`` with the trip's message and returns the trip.
    latch : EstopLatch
        The servo's own latch.
    """

    def __init__(self, action: str, latch: EstopLatch) -> None:
        self.respond = _FERROR_RESPONSES[require_choice("ferror_action", action, FERROR_ACTIONS)]
        self.action, self.latch = action, latch
        self.trips = 0

    def check(self, limit: FollowingErrorLimit, error_m: float, velocity_m_s: float,
              stamp_ns: int) -> FerrorTrip | None:
        """The trip of this sample (``error_m`` [m], reference ``velocity_m_s`` [m/s]) after its response; else None."""
        trip = following_error_trip(limit, error_m, velocity_m_s, stamp_ns)
        if trip is not None:
            self.trips += 1
            self.respond(self.latch, trip)
        return trip


#: The diagnostic keys of a latch's state (:meth:`EstopLatch.state`) that :class:`MachineWatch` reads.
LATCH_KEYS = ("enabled", "estop_latched", "estop_cause")


class MachineWatch:
    """The machine's state from its nodes' latch reports: running, or stopped naming the first cause.

    A node reports its latch (:meth:`EstopLatch.state` as key/values); it blocks
    while latched or disabled. The machine is stopped while any node blocks;
    its cause is that of the first node that blocked (a following-error trip
    names the axis; the nodes it e-stopped name the e-stop topic).
    """

    def __init__(self) -> None:
        self._blocking: dict[str, str] = {}  # node -> cause, in the order they blocked

    @staticmethod
    def reports_latch(values: Mapping[str, str]) -> bool:
        """True when ``values`` carry a latch's state."""
        return all(key in values for key in LATCH_KEYS)

    def observe(self, node: str, values: Mapping[str, str]) -> None:
        """Note ``node``'s latch state (``values`` with :data:`LATCH_KEYS`); other reports are ignored."""
        if not self.reports_latch(values):
            return
        latched, enabled = values["estop_latched"] == "true", values["enabled"] == "true"
        if not latched and enabled:
            self._blocking.pop(node, None)
        else:  # a node keeps its place (the first to block names the stop), its cause is its latest
            self._blocking[node] = f"{node}: " + (f"e-stop latched ({values['estop_cause']})" if latched
                                                   else "disabled (~/enable false)")

    @property
    def stopped(self) -> bool:
        """True while some node blocks its commands."""
        return bool(self._blocking)

    @property
    def cause(self) -> str:
        """Why the machine is stopped: the first blocking node and its cause ("" while it runs)."""
        return next(iter(self._blocking.values()), "")

    def blocking(self) -> tuple[str, ...]:
        """The nodes that block now, in the order they blocked."""
        return tuple(self._blocking)
