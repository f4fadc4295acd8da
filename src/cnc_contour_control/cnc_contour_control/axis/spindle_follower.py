"""The servo's side of the spindle: the commanded speed by tick stamp, handed to a law that follows it (ROS-free).

A real CNC commands the spindle, so its servo knows the speed. A servo
config's ``spindle_schedule_t_s``/``spindle_schedule_rpm`` hold it piecewise
constant (``rpms[i]`` from ``times_s[i]`` on, as the plant's schedule does);
the engine's servo stage and the servo node call
:meth:`SpindleFollower.follow` with each tick's stamp (integer ns) before the
tick's sample, so both redesign at the same tick. A law that follows the
spindle has :meth:`~cnc_contour_control.laws.base.SpindleFollowing.set_spindle_rpm`
(paper 002's PDC redesigns L and W for the new f_d, keeping its filter
history); a speed it cannot design for is refused and the law keeps its last
valid design.
"""
from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from typing import Any

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.laws.base import SpindleFollowing


def _numbers(name: str, values: Any) -> tuple[float, ...]:
    if isinstance(values, (str, bytes)) or not isinstance(values, Sequence):
        raise ConfigError(f"{name} must be a list of numbers, got {values!r}")
    if any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in values):
        raise ConfigError(f"{name} must hold finite numbers, got {list(values)!r}")
    return tuple(float(v) for v in values)


def spindle_schedule(times_s: Any, rpms: Any) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The schedule's two lists as float tuples, checked: one rpm > 0 per time, times >= 0, strictly increasing."""
    times, speeds = _numbers("spindle_schedule_t_s", times_s), _numbers("spindle_schedule_rpm", rpms)
    if len(times) != len(speeds):
        raise ConfigError(f"spindle_schedule_rpm must have one entry per spindle_schedule_t_s ({len(times)}), "
                          f"got {len(speeds)}")
    for i, (t, rpm) in enumerate(zip(times, speeds)):
        if t < 0.0 or (i and t <= times[i - 1]):
            bound = f"> {times[i - 1]:g}" if i else ">= 0"
            raise ConfigError(f"spindle_schedule_t_s[{i}] must be {bound}, got {t:g}")
        if rpm <= 0.0:
            raise ConfigError(f"spindle_schedule_rpm[{i}] must be > 0, got {rpm:g}")
    return times, speeds


class SpindleFollower:
    """The commanded spindle speed by tick stamp, handed to a law when it changes.

    Parameters
    ----------
    law : SpindleFollowing
        The law that redesigns for the speed.
    times_s, rpms : sequence of float
        The schedule (checked by :func:`spindle_schedule`): ``rpms[i]`` from ``times_s[i]`` on [s, rpm].

    Attributes
    ----------
    commanded_rpm : float or None
        The speed of the last tick [rpm] (None before the schedule's first time).
    redesigns : int
        How many times the law redesigned.
    """

    def __init__(self, law: SpindleFollowing, times_s: Sequence[float], rpms: Sequence[float]) -> None:
        self.law = law
        self._times_ns = [round(t * 1e9) for t in times_s]
        self._rpms = tuple(rpms)
        self.commanded_rpm: float | None = None
        self.redesigns = 0

    def rpm_at(self, stamp_ns: int) -> float | None:
        """The commanded speed at ``stamp_ns`` [rpm] (None before the schedule's first time)."""
        piece = bisect.bisect_right(self._times_ns, stamp_ns) - 1
        return self._rpms[piece] if piece >= 0 else None

    def follow(self, stamp_ns: int) -> str | None:
        """Hand the tick's speed to the law when it changed; the refusal's reason (once per change), else None."""
        rpm = self.rpm_at(stamp_ns)
        if rpm is None or rpm == self.commanded_rpm:
            return None
        self.commanded_rpm = rpm
        return self.apply()

    def apply(self) -> str | None:
        """Redesign the law for the commanded speed (also after a retune); the refusal's reason, else None."""
        if self.commanded_rpm is None:
            return None
        try:
            self.redesigns += bool(self.law.set_spindle_rpm(self.commanded_rpm))
        except ConfigError as err:
            return str(err)
        return None
