"""Peak-keeping decimation: per window of stamp time, the samples holding the window's minimum and maximum.

A window of ``window_ns`` gives at most two samples (the minimum's and the maximum's, in stamp order; one when
they are the same sample), so ``window_ns = 20 ms`` streams at most 100 samples per simulated second, and every
extreme of the signal (its peak of either sign, hence its peak magnitude) reaches the viewer exactly as it
was. Windows are aligned to multiples of ``window_ns``; a sample opens the next window when its stamp leaves
the current one. ROS-free and clock-free: stamps come in with the samples.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import numpy as np

from cnc_contour_control.core.errors import ConfigError

T = TypeVar("T")

#: Default window: 20 ms of stamp time, so at most 100 samples per simulated second.
WINDOW_NS = 20_000_000


def window_runs(stamps_ns: Any, window_ns: int) -> list[tuple[int, int]]:
    """(start, end) index ranges of ascending ``stamps_ns`` that share a window."""
    windows = np.asarray(stamps_ns, np.int64) // window_ns
    bounds = [0, *(np.flatnonzero(windows[1:] != windows[:-1]) + 1).tolist(), int(windows.size)]
    return list(zip(bounds[:-1], bounds[1:]))


@dataclass
class _Held(Generic[T]):
    stamp_ns: int
    value: float
    payload: T


class PeakDecimator(Generic[T]):
    """Keeps the min and the max sample of each window; :meth:`push` returns the samples of closed windows."""

    def __init__(self, window_ns: int = WINDOW_NS) -> None:
        if window_ns <= 0:
            raise ConfigError(f"window_ns must be > 0, got {window_ns}")
        self.window_ns = int(window_ns)
        self._window: int | None = None
        self._low: _Held[T] | None = None
        self._high: _Held[T] | None = None

    def push(self, stamp_ns: int, value: float, payload: T) -> list[T]:
        """Add one sample; the payloads of the window it closed (0, 1 or 2, in stamp order)."""
        window = stamp_ns // self.window_ns
        out = self.flush() if self._window is not None and window != self._window else []
        self._window = window
        if self._low is None or value < self._low.value:
            self._low = _Held(stamp_ns, value, payload)
        if self._high is None or value > self._high.value:
            self._high = _Held(stamp_ns, value, payload)
        return out

    def push_many(self, stamps_ns: Any, values: Any, make: Callable[[int], T]) -> list[tuple[T, int]]:
        """:meth:`push` for a batch (ascending stamps, numpy arrays): the same samples kept, each with the index of
        the batch sample that closed its window; ``make(i)`` builds a payload, only for a window's min and max."""
        out: list[tuple[T, int]] = []
        for start, end in window_runs(stamps_ns, self.window_ns):
            window = int(stamps_ns[start]) // self.window_ns
            if self._window is not None and window != self._window:
                out.extend((payload, start) for payload in self.flush())
            self._window = window
            chunk = values[start:end]
            low, high = start + int(np.argmin(chunk)), start + int(np.argmax(chunk))  # first of equals, as push
            if self._low is None or values[low] < self._low.value:
                self._low = _Held(int(stamps_ns[low]), float(values[low]), make(low))
            if self._high is None or values[high] > self._high.value:
                self._high = _Held(int(stamps_ns[high]), float(values[high]), make(high))
        return out

    def flush(self) -> list[T]:
        """Close the current window: its min and max payloads in stamp order (the run's end calls it)."""
        low, high = self._low, self._high
        self._window, self._low, self._high = None, None, None
        if low is None or high is None:
            return []
        if low is high or low.stamp_ns == high.stamp_ns:
            return [low.payload]
        first, second = (low, high) if low.stamp_ns < high.stamp_ns else (high, low)
        return [first.payload, second.payload]


class LastInWindow(Generic[T]):
    """Keeps the last sample of each window (for values drawn, not judged: the XY trace, the override)."""

    def __init__(self, window_ns: int = WINDOW_NS) -> None:
        if window_ns <= 0:
            raise ConfigError(f"window_ns must be > 0, got {window_ns}")
        self.window_ns = int(window_ns)
        self._window: int | None = None
        self._last: T | None = None

    def push(self, stamp_ns: int, payload: T) -> list[T]:
        """Add one sample; the last payload of the window it closed, if it closed one."""
        window = stamp_ns // self.window_ns
        out = self.flush() if self._window is not None and window != self._window else []
        self._window, self._last = window, payload
        return out

    def push_many(self, stamps_ns: Any, make: Callable[[int], T]) -> list[tuple[T, int]]:
        """:meth:`push` for a batch (ascending stamps): the last payloads of the windows it closed, each with the
        index of the batch sample that closed it; ``make(i)`` builds a payload, once per window run."""
        out: list[tuple[T, int]] = []
        for start, end in window_runs(stamps_ns, self.window_ns):
            window = int(stamps_ns[start]) // self.window_ns
            if self._window is not None and window != self._window:
                out.extend((payload, start) for payload in self.flush())
            self._window, self._last = window, make(end - 1)
        return out

    def flush(self) -> list[T]:
        """Close the current window."""
        last, self._last, self._window = self._last, None, None
        return [] if last is None else [last]
