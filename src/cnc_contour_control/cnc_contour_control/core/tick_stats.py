"""Per-window statistics of a node's ticks, for diagnostics every second of run time (ROS-free).

In the manner of diagnostic_updater, each node reports once per window, but
the window is one second of the *run's* clock (the tick stamps), so a
lockstep run reports at the same stamps every time and the bag stays
reproducible. A window's values::

    ticks            ticks in the window
    tick_rate_hz     ticks / wall seconds since the previous window (real-time pace)
    <count>          hits of a counter in the window
    <count>_share    hits / (its denominator summed over the window), in [0, 1]
    <peak>           largest |value| in the window

Wall time comes in as an argument; nothing here reads a clock.
"""
from __future__ import annotations

from collections.abc import Mapping

from cnc_contour_control.core.lockstep import NS_PER_S

__all__ = ["TickStats"]


class TickStats:
    """Counts, shares and peaks per window of ``window_ns`` of run time.

    Parameters
    ----------
    window_ns : int
        Length of a window in run time [ns] (> 0); windows end at multiples of it.
    """

    def __init__(self, window_ns: int = NS_PER_S) -> None:
        if window_ns <= 0:
            raise ValueError(f"window_ns must be > 0, got {window_ns}")
        self.window_ns = int(window_ns)
        self._next_ns = self.window_ns
        self._wall_s: float | None = None
        self._clear()

    def _clear(self) -> None:
        self.ticks = 0
        self._hits: dict[str, int] = {}
        self._totals: dict[str, int] = {}
        self._peaks: dict[str, float] = {}

    def add(self, stamp_ns: int, wall_s: float, counts: Mapping[str, tuple[int, int]] | None = None,
            peaks: Mapping[str, float] | None = None) -> dict[str, str] | None:
        """Account the tick at ``stamp_ns``; the closed window's values when the stamp reached its end.

        ``counts`` maps a name to (hits, out of) for this tick; ``peaks`` a name to a value whose
        largest magnitude is kept.
        """
        if self._wall_s is None:
            self._wall_s = wall_s
        self.ticks += 1
        for name, (hits, total) in (counts or {}).items():
            self._hits[name] = self._hits.get(name, 0) + int(hits)
            self._totals[name] = self._totals.get(name, 0) + int(total)
        for name, value in (peaks or {}).items():
            self._peaks[name] = max(self._peaks.get(name, 0.0), abs(value))
        if stamp_ns < self._next_ns:
            return None
        values = self._values(stamp_ns, wall_s)
        self._next_ns = (stamp_ns // self.window_ns + 1) * self.window_ns
        self._wall_s = wall_s
        self._clear()
        return values

    def _values(self, stamp_ns: int, wall_s: float) -> dict[str, str]:
        """The window's values as diagnostic strings."""
        elapsed_s = wall_s - (self._wall_s if self._wall_s is not None else wall_s)
        values = {"run_time_s": f"{stamp_ns / NS_PER_S:.6f}", "ticks": str(self.ticks),
                  "tick_rate_hz": f"{self.ticks / elapsed_s:.1f}" if elapsed_s > 0 else "nan"}
        for name, hits in self._hits.items():
            total = self._totals[name]
            values[name] = str(hits)
            values[f"{name}_share"] = f"{hits / total:.4f}" if total else "0"
        values.update({name: f"{peak:.9g}" for name, peak in self._peaks.items()})
        return values
