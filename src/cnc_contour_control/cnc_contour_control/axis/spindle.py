"""The spindle speed over a run and the tooth-passing phase it drives (paper 002, Eq. 2; ROS-free).

``f_d = spindle_rpm · flutes / 60``. A schedule holds the speed piecewise
constant (a spindle override changes it at given times) and integrates the
phase ``φ(t) = 2π ∫ f_d dt``, continuous across every change, so a periodic
cutting disturbance ``A sin(φ(t) + θ)`` changes its frequency without a jump.
The plant (``cnc_plant_sim.models.velocity_loop``) draws its disturbance from it; a
law that must follow the spindle can read the same schedule.
"""
from __future__ import annotations

import bisect
import math
from collections.abc import Sequence


class SpindleSchedule:
    """Tooth-passing frequency f_d(t), piecewise constant, and its phase φ(t) = 2π ∫ f_d dt (continuous).

    Parameters
    ----------
    start_times_s : sequence of float
        Start of each piece [s], the first 0, increasing.
    frequencies_hz : sequence of float
        f_d of each piece [Hz], one per start time.
    """

    def __init__(self, start_times_s: Sequence[float], frequencies_hz: Sequence[float]) -> None:
        self.start_times_s, self.frequencies_hz = tuple(start_times_s), tuple(frequencies_hz)
        phases = [0.0]
        for k in range(1, len(self.start_times_s)):
            span = self.start_times_s[k] - self.start_times_s[k - 1]
            phases.append(phases[-1] + 2.0 * math.pi * self.frequencies_hz[k - 1] * span)
        self._start_phases = phases

    @classmethod
    def from_rpm(cls, spindle_rpm: float, flutes: int, change_times_s: Sequence[float] = (),
                 change_rpms: Sequence[float] = ()) -> SpindleSchedule:
        """``spindle_rpm`` from t = 0, then ``change_rpms[i]`` from ``change_times_s[i]`` on."""
        rpms = (spindle_rpm, *change_rpms)
        return cls((0.0, *change_times_s), tuple(r * flutes / 60.0 for r in rpms))

    def _piece(self, t_s: float) -> int:
        return max(bisect.bisect_right(self.start_times_s, t_s) - 1, 0)

    def frequency_hz(self, t_s: float) -> float:
        """f_d at ``t_s`` [Hz]."""
        return self.frequencies_hz[self._piece(t_s)]

    def phase_rad(self, t_s: float) -> float:
        """φ(t_s) [rad]."""
        k = self._piece(t_s)
        return self._start_phases[k] + 2.0 * math.pi * self.frequencies_hz[k] * (t_s - self.start_times_s[k])
