"""Simulation time of a run: ticks, stamps, the end of the run and its summary (ROS-free)."""
from __future__ import annotations

from dataclasses import dataclass

from cnc_contour_control.core.lockstep import NS_PER_S, duration_to_ns, seconds_to_ns


@dataclass
class RunClock:
    """Counts ticks of a run of ``duration_s`` at ``sample_time_s``.

    Tick k is stamped ``k * sample_time_ns`` in lockstep; in real time the
    stamp advances by the measured period (``advance(period_ns)``).
    """

    sample_time_s: float
    duration_s: float
    tick: int = 0
    stamp_ns: int = 0
    late_commands: int = 0
    started_wall_s: float | None = None
    finished_wall_s: float | None = None

    def __post_init__(self) -> None:
        self.sample_time_ns = seconds_to_ns(self.sample_time_s)
        self.end_ns = duration_to_ns(self.duration_s)

    def advance(self, period_ns: int | None = None) -> None:
        """Move to the next tick (by the nominal or a measured period)."""
        self.tick += 1
        if period_ns is None:
            self.stamp_ns = self.tick * self.sample_time_ns
        else:
            self.stamp_ns += period_ns

    @property
    def done(self) -> bool:
        """True once the stamp has passed the run's duration."""
        return self.stamp_ns > self.end_ns

    def summary(self, faults: list[str], now_wall_s: float) -> dict[str, object]:
        """Ticks, simulated and wall time (to the end, or to ``now_wall_s`` while running), real-time factor."""
        end_s = self.finished_wall_s if self.finished_wall_s is not None else now_wall_s
        wall_s = end_s - (self.started_wall_s if self.started_wall_s is not None else end_s)
        sim_s = self.stamp_ns / NS_PER_S
        return {
            "ticks": self.tick,
            "simulated_time_s": sim_s,
            "wall_time_s": wall_s,
            "real_time_factor": sim_s / wall_s if wall_s > 0 else float("nan"),
            "late_commands": self.late_commands,
            "faults": list(faults),
        }
