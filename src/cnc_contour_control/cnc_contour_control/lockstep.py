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

from cnc_contour_control.errors import ConfigError, FaultError

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


def tick_stamp_ns(tick: int, sample_time_ns: int) -> int:
    """Stamp of tick ``tick`` in integer nanoseconds."""
    return tick * sample_time_ns


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


@dataclass
class _Pending:
    first_arrival_s: float
    items: dict[str, Any] = field(default_factory=dict)


class StampMatcher:
    """Collects the inputs of each tick and releases a tick once all are there.

    Parameters
    ----------
    required : sequence of str
        Names of the inputs (topics) every tick needs.
    timeout_s : float
        Wall-time a tick may wait, from its first input, before
        :meth:`overdue` reports it.
    startup_timeout_s : float, optional
        The same for the first tick, which also waits for discovery of the
        graph (default: ``timeout_s``).
    """

    def __init__(self, required: Sequence[str], timeout_s: float, startup_timeout_s: float | None = None) -> None:
        if not required:
            raise ConfigError("StampMatcher needs at least one required input")
        if not timeout_s > 0.0:
            raise ConfigError(f"timeout_s must be > 0, got {timeout_s!r}")
        startup = timeout_s if startup_timeout_s is None else startup_timeout_s
        if not startup >= timeout_s:
            raise ConfigError(f"startup_timeout_s must be >= timeout_s ({timeout_s}), got {startup!r}")
        self.required = tuple(required)
        self.timeout_s = float(timeout_s)
        self.startup_timeout_s = float(startup)
        self._pending: dict[int, _Pending] = {}
        self._last_released_ns: int | None = None

    def add(self, name: str, stamp_ns: int, item: Any, now_s: float) -> dict[str, Any] | None:
        """Store one input; return all inputs of the tick if it is now complete.

        Inputs stamped at or before the last released tick are stale and ignored
        (they can only be late duplicates). Raises :class:`FaultError` for an
        unknown input name.
        """
        if name not in self.required:
            raise FaultError(f"unexpected input {name!r}; this stage takes {list(self.required)}")
        if self._last_released_ns is not None and stamp_ns <= self._last_released_ns:
            return None
        pending = self._pending.setdefault(stamp_ns, _Pending(now_s))
        pending.items[name] = item
        if len(pending.items) < len(self.required):
            return None
        del self._pending[stamp_ns]
        self._last_released_ns = stamp_ns
        return pending.items

    def expect(self, stamp_ns: int, now_s: float) -> None:
        """Start waiting for tick ``stamp_ns`` now, before any of its inputs arrived."""
        self._pending.setdefault(stamp_ns, _Pending(now_s))

    def overdue(self, now_s: float) -> tuple[int, list[str]] | None:
        """The oldest incomplete tick waiting longer than the timeout, with its missing inputs."""
        if not self._pending:
            return None
        stamp_ns = min(self._pending)
        pending = self._pending[stamp_ns]
        if now_s - pending.first_arrival_s <= self.current_timeout_s:
            return None
        missing = [name for name in self.required if name not in pending.items]
        return stamp_ns, missing

    @property
    def current_timeout_s(self) -> float:
        """The start-up timeout until the first tick is released, then the per-tick one."""
        return self.startup_timeout_s if self._last_released_ns is None else self.timeout_s

    @property
    def pending_count(self) -> int:
        """Number of incomplete ticks held."""
        return len(self._pending)
