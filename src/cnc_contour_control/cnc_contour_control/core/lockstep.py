"""Lockstep bookkeeping: match messages by stamp, detect missing ones, check data.

ROS-free. A node feeds every arriving message's stamp (integer nanoseconds)
into a :class:`StampMatcher`; once every required input holds the same stamp,
the tick is complete. Wall time comes in as an argument, so the watchdog is
testable without a clock.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from cnc_contour_control.core.errors import ConfigError, FaultError, InputFault

NS_PER_S = 1_000_000_000


def ns_to_s(stamp_ns: int) -> float:
    """Integer nanoseconds to float seconds (the one conversion every stage uses)."""
    return stamp_ns * 1e-9


def split_ns(stamp_ns: int) -> tuple[int, int]:
    """Integer nanoseconds to (sec, nanosec), the fields of builtin_interfaces/Time."""
    sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
    return sec, nanosec


def join_ns(sec: int, nanosec: int) -> int:
    """(sec, nanosec) of builtin_interfaces/Time to integer nanoseconds."""
    return int(sec) * NS_PER_S + int(nanosec)


def seconds_to_ns(value_s: float, name: str = "sample_time_s") -> int:
    """Seconds to integer nanoseconds; refuses values that are not whole nanoseconds > 0."""
    if not math.isfinite(value_s) or value_s <= 0.0:
        raise ConfigError(f"{name} must be > 0, got {value_s!r}")
    value_ns = round(value_s * NS_PER_S)
    if abs(value_ns - value_s * NS_PER_S) > 1e-3:
        raise ConfigError(f"{name} must be a whole number of nanoseconds, got {value_s!r}")
    return int(value_ns)


def duration_to_ns(duration_s: float) -> int:
    """A run's duration in integer nanoseconds (rounded; need not be a whole tick)."""
    if not math.isfinite(duration_s) or duration_s <= 0.0:
        raise ConfigError(f"duration_s must be > 0, got {duration_s!r}")
    return int(round(duration_s * NS_PER_S))


def require_finite_values(values: Iterable[float], what: str) -> None:
    """Raise :class:`FaultError` naming ``what`` and the index if a value is not finite."""
    for index, value in enumerate(values):
        if not math.isfinite(value):
            raise FaultError(f"non-finite value in {what}[{index}]: {value!r}")


def require_same_axes(received: Sequence[str], expected: Sequence[str], what: str) -> None:
    """Raise :class:`FaultError` if a message's axis names differ from the configured ones."""
    if tuple(received) != tuple(expected):
        raise FaultError(f"{what} carries axes {list(received)}, expected {list(expected)}")


#: A message may be stamped at most this far after the last completed tick (see :func:`stamp_horizon_ns`).
HORIZON_TICKS = 10
#: ... and never less than this (real-time periods stretch under load).
MIN_HORIZON_NS = NS_PER_S
#: The largest sample time the nodes accept (their ``sample_time_s`` range), for stages that do not know T.
MAX_SAMPLE_TIME_NS = NS_PER_S


def stamp_horizon_ns(sample_time_ns: int | None = None) -> int:
    """How far past the last completed tick an input's stamp may lie: max(1 s, 10 T).

    In lockstep the next tick is exactly T ahead; in real time the measured
    period stretches under load, hence the margin. A stage that does not know T
    (``None``) takes the largest T the nodes accept. A stamp beyond it comes from
    outside the run (or a broken clock) and is a fault, never a stalled run.
    """
    period_ns = MAX_SAMPLE_TIME_NS if sample_time_ns is None else int(sample_time_ns)
    return max(MIN_HORIZON_NS, HORIZON_TICKS * period_ns)


@dataclass
class _Pending:
    first_arrival_s: float
    items: dict[str, Any] = field(default_factory=dict)


class StampMatcher:
    """Collects the inputs of each tick and releases a tick once all are there.

    Rules (each broken one is a :class:`FaultError` naming the input): an
    input stamped at or before the last released tick is stale and ignored
    (callers check its values first); one stamped more than ``max_ahead_ns``
    after the last released (or expected) tick and after the same input's
    latest earlier stamp held, or a second input of the same
    name for a pending tick, or a pending tick passed by a later complete one,
    comes from outside the run.

    Parameters
    ----------
    required : sequence of str
        Names of the inputs (topics) every tick needs.
    timeout_s : float
        Wall-time a tick may wait, from its first input or the release of the
        tick before (whichever is later), before :meth:`overdue` reports it.
    startup_timeout_s : float, optional
        The same for the first tick, which also waits for discovery of the
        graph (default: ``timeout_s``).
    max_ahead_ns : int, optional
        Horizon for stamps, in ns after the last released or expected tick
        (default: none; see :func:`stamp_horizon_ns`).
    """

    def __init__(self, required: Sequence[str], timeout_s: float, startup_timeout_s: float | None = None,
                 max_ahead_ns: int | None = None) -> None:
        if not required:
            raise ConfigError("StampMatcher needs at least one required input")
        if not timeout_s > 0.0:
            raise ConfigError(f"timeout_s must be > 0, got {timeout_s!r}")
        startup = timeout_s if startup_timeout_s is None else startup_timeout_s
        if not startup >= timeout_s:
            raise ConfigError(f"startup_timeout_s must be >= timeout_s ({timeout_s}), got {startup!r}")
        if max_ahead_ns is not None and not max_ahead_ns >= 0:
            raise ConfigError(f"max_ahead_ns must be >= 0, got {max_ahead_ns!r}")
        self.required = tuple(required)
        self.timeout_s = float(timeout_s)
        self.startup_timeout_s = float(startup)
        self.max_ahead_ns = max_ahead_ns
        self._pending: dict[int, _Pending] = {}
        self._last_released_ns: int | None = None
        self._expected_ns: int | None = None
        self._released_at_s: float | None = None
        self._latest_ns: dict[str, int] = {}  # per input, its latest stamp held or released
        self._unchecked: list[tuple[str, int]] = []  # inputs held before any tick was released or expected

    @property
    def last_released_ns(self) -> int | None:
        """Stamp of the last tick released (None before the first)."""
        return self._last_released_ns

    def add(self, name: str, stamp_ns: int, item: Any, now_s: float) -> dict[str, Any] | None:
        """Store one input; return all inputs of the tick if it is now complete.

        Returns None for a stale input (stamped at or before the last released
        tick). Raises :class:`FaultError` for an unknown input name and for the
        rules in the class docstring.
        """
        if name not in self.required:
            raise FaultError(f"unexpected input {name!r}; this stage takes {list(self.required)}")
        if self._last_released_ns is not None and stamp_ns <= self._last_released_ns:
            return None
        if self._last_released_ns is None and self._expected_ns is None:
            self._unchecked.append((name, stamp_ns))  # nothing to compare with yet: checked at the first release
        else:
            previous_ns = self._latest_ns.get(name)
            self._check_horizon(name, stamp_ns, previous_ns if previous_ns is not None and previous_ns < stamp_ns
                                else None)
        self._latest_ns[name] = max(stamp_ns, self._latest_ns.get(name, stamp_ns))
        pending = self._pending.get(stamp_ns)
        if pending is None:  # (not setdefault: that builds a _Pending for every input of a tick)
            pending = self._pending[stamp_ns] = _Pending(now_s)
        if name in pending.items:
            raise InputFault(name, f"{name}: a second message for tick t={ns_to_s(stamp_ns):.6f} s "
                             "(another publisher outside the run?)")
        pending.items[name] = item
        if len(pending.items) < len(self.required):
            return None
        return self._release(stamp_ns, now_s)

    def _release(self, stamp_ns: int, now_s: float) -> dict[str, Any]:
        items = self._pending.pop(stamp_ns).items
        self._last_released_ns, self._released_at_s = stamp_ns, now_s
        if self._pending:  # in lockstep nothing else is pending at a release: the checks below cost nothing then
            self._drop_passed(stamp_ns)
        if self._unchecked:
            self._check_held()
        return items

    def _drop_passed(self, stamp_ns: int) -> None:
        """Forget expected ticks that never came; a tick with inputs that a later one passed is a fault."""
        for waited_ns in [s for s, p in self._pending.items() if s < stamp_ns and not p.items]:
            del self._pending[waited_ns]  # an expected tick that never came (the run started later)
        passed = sorted(s for s in self._pending if s < stamp_ns)
        if passed:
            names = ", ".join(self._pending[passed[0]].items)
            raise FaultError(f"{names} stamped t={ns_to_s(passed[0]):.6f} s never completed a tick and was "
                             f"passed by tick t={ns_to_s(stamp_ns):.6f} s (a message from outside the run?)")

    def _check_held(self) -> None:
        """Check the horizon of the inputs held before the first release, now that there is a base."""
        held, self._unchecked = self._unchecked, []
        previous: dict[str, int] = {}
        for name, later_ns in sorted(held, key=lambda item: item[1]):
            if later_ns in self._pending and name in self._pending[later_ns].items:
                self._check_horizon(name, later_ns, previous.get(name))
                previous[name] = later_ns

    def _check_horizon(self, name: str, stamp_ns: int, previous_ns: int | None = None) -> None:
        # The base is the last released or expected tick, or this input's own previous stamp: in real time a
        # stage may lag, holding one input's stream while the producer of another input catches up.
        if self.max_ahead_ns is None:
            return
        base_ns = self._last_released_ns
        for other_ns in (self._expected_ns, previous_ns):  # the latest known stamp, without building a list
            if other_ns is not None and (base_ns is None or other_ns > base_ns):
                base_ns = other_ns
        if base_ns is not None and stamp_ns - base_ns > self.max_ahead_ns:
            raise InputFault(name, f"{name} stamped t={ns_to_s(stamp_ns):.6f} s, more than "
                             f"{ns_to_s(self.max_ahead_ns)} s after tick t={ns_to_s(base_ns):.6f} s "
                             "(a message from outside the run?)")

    def expect(self, stamp_ns: int, now_s: float) -> None:
        """Start waiting for tick ``stamp_ns`` now, before any of its inputs arrived."""
        self._pending.setdefault(stamp_ns, _Pending(now_s))
        self._expected_ns = stamp_ns if self._expected_ns is None else max(self._expected_ns, stamp_ns)

    def overdue(self, now_s: float) -> tuple[int, list[str]] | None:
        """The oldest incomplete tick waiting longer than the timeout, with its missing inputs."""
        if not self._pending:
            return None
        stamp_ns = min(self._pending)
        pending = self._pending[stamp_ns]
        since_s = pending.first_arrival_s if self._released_at_s is None else max(pending.first_arrival_s,
                                                                                   self._released_at_s)
        if now_s - since_s <= self.current_timeout_s:
            return None
        missing = [name for name in self.required if name not in pending.items]
        return stamp_ns, missing

    def waiting_for(self, now_s: float, after_s: float) -> list[str]:
        """The inputs a node waits for: those of the oldest tick pending longer than ``after_s``, or before the
        first release those never received (the caller knows how long it has been up)."""
        if self._pending:
            stamp_ns = min(self._pending)
            pending = self._pending[stamp_ns]
            since_s = max(pending.first_arrival_s, self._released_at_s or pending.first_arrival_s)
            return [n for n in self.required if n not in pending.items] if now_s - since_s > after_s else []
        if self._last_released_ns is None:
            return [n for n in self.required if n not in self._latest_ns]
        return []

    @property
    def current_timeout_s(self) -> float:
        """The start-up timeout until the first tick is released, then the per-tick one."""
        return self.startup_timeout_s if self._last_released_ns is None else self.timeout_s

    @property
    def pending_count(self) -> int:
        """Number of incomplete ticks held."""
        return len(self._pending)
