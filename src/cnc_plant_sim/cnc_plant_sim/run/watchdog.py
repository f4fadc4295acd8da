"""The plant's command watchdog in real-time mode (ros2_control's cmd_timeout semantics; ROS-free).

Every real-time tick, per axis: a command that arrived for the tick's stamp
is fresh; otherwise it is *late* (counted) and the last command is held,
unless the last fresh one is older than ``command_max_age_s``: then the
command is replaced by the safe hold, a zero command (counted as *held*).
For every plant of :data:`cnc_plant_sim.models.plant.PLANTS` zero means "no drive":
the force/voltage-commanded feed drives coast to rest under friction, the
velocity-commanded axes (papers 002/003) stop and hold their position.

Once ``late_share_min_ticks`` ticks have run, a share of late commands
(late / (ticks · axes)) above ``max_late_share`` is a fault: a run whose
loop does not keep its deadline ends faulted instead of reporting no fault.
The run's share alone would let a long run hide a stalled second (a servo
stopped for 1 s of a 10 s run is 10 %): so, per axis, a share above
``max_late_share_window`` within any ``late_window_ticks`` consecutive ticks
is a fault too, naming the axis and the window's time.
A plant that cannot tick at its own period would count none of this: each
tick's commands arrive within the stretched period, and a run asked for at
10 kHz that ticked at 2 kHz would say finished. So, given the sample time,
the mean period of the window's ticks above ``max_period_ratio`` times it is
a fault too: the machine does not hold the period in real time.
Lockstep runs wait for every command and never consult the watchdog.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.core.lockstep import seconds_to_ns
from cnc_contour_control.core.params import check_ranges, param

__all__ = ["CommandWatchdog", "WatchdogParams"]


@dataclass(frozen=True)
class WatchdogParams:
    """The watchdog's parameters (the plant's run parameters inherit them)."""

    command_max_age_s: float = param(0.1, unit="s", low=1.0e-5, high=3600.0, read_only=True,
                                     description="real time: a command older than this is replaced by a zero "
                                                 "command (safe hold)")
    max_late_share: float = param(0.25, low=0.0, high=1.0, read_only=True,
                                  description="real time: a share of late commands above this faults the run "
                                              "(1: never)")
    late_share_min_ticks: int = param(100, low=1, high=1_000_000_000, read_only=True,
                                      description="real time: ticks before the late share is judged")
    max_late_share_window: float = param(0.5, low=0.0, high=1.0, read_only=True,
                                         description="real time: one axis's share of late commands within any "
                                                     "late_window_ticks ticks above this faults the run (1: never)")
    late_window_ticks: int = param(100, low=1, high=1_000_000_000, read_only=True,
                                   description="real time: ticks of the window max_late_share_window is judged on")
    max_period_ratio: float = param(2.0, low=0.0, high=1.0e6, read_only=True,
                                    description="real time: the plant's mean tick period within any "
                                                "late_window_ticks ticks above this multiple of sample_time_s "
                                                "faults the run (0: never)")

    def __post_init__(self) -> None:
        check_ranges(self)


class CommandWatchdog:
    """Late and stale commands of ``n_axes`` axes (see the module docstring).

    Parameters
    ----------
    params : WatchdogParams
        Limits (any object with its fields, e.g. ``PlantRunParams``).
    n_axes : int
        Number of axes (commands per tick).
    axis_names : sequence of str, optional
        The axes' names, for the faults (default: their indices).
    sample_time_s : float, optional
        The period the ticks should keep (s); None: their period is not judged.
    """

    def __init__(self, params: WatchdogParams, n_axes: int, axis_names: Sequence[str] = (),
                 sample_time_s: float | None = None) -> None:
        self.params = params
        self.sample_time_s = sample_time_s
        self.n_axes = int(n_axes)
        self.axis_names = tuple(axis_names) or tuple(str(i) for i in range(self.n_axes))
        self.max_age_ns = seconds_to_ns(params.command_max_age_s)
        self.reset()

    def reset(self) -> None:
        """No ticks, no late commands; every axis fresh at stamp 0."""
        self.ticks = 0
        self.late_commands = 0
        self.held_commands = 0
        self._fresh_ns = [0] * self.n_axes
        self._window: deque[tuple[int, tuple[bool, ...]]] = deque()  # (stamp, late per axis) of the last ticks
        self._window_late = [0] * self.n_axes

    def tick(self, stamp_ns: int, received: Sequence[bool], commands: Sequence[float]) -> list[float]:
        """The commands to apply at ``stamp_ns``: fresh ones, held late ones, zero for stale ones."""
        out = list(commands)
        for i, fresh in enumerate(received):
            if fresh:
                self._fresh_ns[i] = stamp_ns
                continue
            self.late_commands += 1
            if stamp_ns - self._fresh_ns[i] > self.max_age_ns:
                out[i] = 0.0
                self.held_commands += 1
        self.ticks += 1
        self._slide(stamp_ns, tuple(not fresh for fresh in received))
        return out

    def _slide(self, stamp_ns: int, late: tuple[bool, ...]) -> None:
        """Add this tick's late flags to the window and drop the tick that left it."""
        self._window.append((stamp_ns, late))
        for i, was_late in enumerate(late):
            self._window_late[i] += was_late
        if len(self._window) > self.params.late_window_ticks:
            for i, was_late in enumerate(self._window.popleft()[1]):
                self._window_late[i] -= was_late

    @property
    def late_share(self) -> float:
        """Late commands / (ticks · axes) so far (0 before the first tick)."""
        return self.late_commands / (self.ticks * self.n_axes) if self.ticks else 0.0

    def check(self) -> None:
        """Raise :class:`FaultError` when the late share exceeds ``max_late_share`` (after the minimum ticks), or
        one axis's share within the last ``late_window_ticks`` ticks exceeds ``max_late_share_window``, or their
        mean period exceeds ``max_period_ratio`` times the sample time."""
        self._check_window()
        self._check_period()
        if self.ticks < self.params.late_share_min_ticks or self.late_share <= self.params.max_late_share:
            return
        raise FaultError(f"plant: {self.late_commands} of {self.ticks * self.n_axes} commands late "
                         f"({100 * self.late_share:.1f} %) after {self.ticks} ticks: late share "
                         f"{self.late_share:.4f} exceeds max_late_share {self.params.max_late_share:g}")

    def _check_window(self) -> None:
        window = self.params.late_window_ticks
        if len(self._window) < window:
            return
        for name, late in zip(self.axis_names, self._window_late, strict=True):
            if late / window > self.params.max_late_share_window:
                start_s, end_s = self._window[0][0] * 1e-9, self._window[-1][0] * 1e-9
                raise FaultError(f"plant: {late} of axis {name}'s {window} commands from t = {start_s:.3f} s to "
                                 f"{end_s:.3f} s late ({100 * late / window:.1f} %): exceeds "
                                 f"max_late_share_window {self.params.max_late_share_window:g} "
                                 f"(late_window_ticks {window})")

    def _check_period(self) -> None:
        window, ratio = self.params.late_window_ticks, self.params.max_period_ratio
        if self.sample_time_s is None or ratio == 0.0 or len(self._window) < max(window, 2):
            return
        start_ns, end_ns = self._window[0][0], self._window[-1][0]
        mean_ns = (end_ns - start_ns) / (len(self._window) - 1)  # in ns: a mean of exactly ratio x T is no fault
        mean_s = mean_ns * 1e-9
        if mean_ns > ratio * round(self.sample_time_s * 1e9):
            raise FaultError(f"plant: ticks from t = {start_ns * 1e-9:.3f} s to {end_ns * 1e-9:.3f} s came every "
                             f"{mean_s * 1e3:.3f} ms on average, {mean_s / self.sample_time_s:.2f} x sample_time_s "
                             f"{self.sample_time_s * 1e3:g} ms: late beyond max_period_ratio {ratio:g} "
                             f"(late_window_ticks {window}); this machine does not hold the period in real time")
