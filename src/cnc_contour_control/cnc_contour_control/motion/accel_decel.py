"""Acceleration/deceleration after interpolation (paper 003, Eq. 13): a filter on the reference samples (ROS-free).

A CNC smooths the interpolated reference per axis before the position loop.
Paper 003 names two kinds, with time constant T_ip:

``exponential``
    A first-order lag, discretised exactly for a held input at the tick
    period T: ``y(k) = y(k−1) + α (x(k) − y(k−1))``, ``α = 1 − e^(−T/T_ip)``.
    On a circle of radius R at feed F it shrinks the radius by about
    ``T_ip² F² / (2R)``.
``linear``
    A moving average over ``n = round(T_ip / T)`` ticks (n >= 1):
    ``y(k) = (x(k) + … + x(k−n+1)) / n`` — linear ramps of length T_ip;
    about ``T_ip² F² / (24R)``.
``none``
    The reference passes unchanged.

The same filter runs on position, velocity and acceleration, so (being
linear and time-invariant) the filtered velocity stays the derivative of the
filtered position to the sampling's order. The filter starts at rest at the
first sample it sees. :func:`filter_coefficients` gives (b, a) for
``scipy.signal.lfilter`` (the test checks the per-sample state update against it).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from cnc_contour_control.core.config import require_choice
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param

#: Largest time constant a config accepts [s].
MAX_TIME_CONSTANT_S = 10.0


@dataclass(frozen=True)
class AccelDecelConfig:
    """The interpolator's acceleration/deceleration (``interpolator.accel_decel``).

    Parameters
    ----------
    kind : str
        One of :data:`ACCEL_DECEL_FILTERS` (``none``, ``exponential``, ``linear``).
    time_constant_s : float
        T_ip [s], in [0, 10]; > 0 unless ``kind`` is ``none``.
    """

    kind: str = param("none", read_only=True, description="acceleration/deceleration: none, exponential, linear")
    time_constant_s: float = param(0.0, unit="s", low=0.0, high=MAX_TIME_CONSTANT_S, read_only=True,
                                   description="time constant T_ip of the acceleration/deceleration")

    def __post_init__(self) -> None:
        require_choice("kind", self.kind, ACCEL_DECEL_FILTERS, "accel_decel")
        check_ranges(self, "accel_decel")
        if self.kind != "none" and self.time_constant_s <= 0.0:
            raise ConfigError(f"accel_decel.time_constant_s must be > 0 for kind {self.kind!r}, "
                              f"got {self.time_constant_s}")


class SampleFilter:
    """One filter over ``n`` channels at a fixed period: ``reset(values)``, ``step(values) -> values``."""

    def reset(self, values: Sequence[float]) -> None:
        """At rest at ``values`` (every past input equal to them)."""
        raise NotImplementedError

    def step(self, values: Sequence[float]) -> list[float]:
        """The filtered ``values`` of this sample (a new list)."""
        raise NotImplementedError


class PassThrough(SampleFilter):
    """No filter."""

    def reset(self, values: Sequence[float]) -> None:
        """Nothing to keep."""

    def step(self, values: Sequence[float]) -> list[float]:
        """``values`` unchanged."""
        return list(values)


class ExponentialFilter(SampleFilter):
    """First-order lag ``y += α (x − y)`` per channel, ``α = 1 − exp(−dt/T_ip)``."""

    def __init__(self, time_constant_s: float, dt_s: float) -> None:
        self.alpha = -math.expm1(-dt_s / time_constant_s)
        self._y: list[float] = []

    def reset(self, values: Sequence[float]) -> None:
        """At rest at ``values``."""
        self._y = [float(v) for v in values]

    def step(self, values: Sequence[float]) -> list[float]:
        """One lag step per channel."""
        alpha = self.alpha
        self._y = out = [y + alpha * (x - y) for x, y in zip(values, self._y)]
        return list(out)


class MovingAverageFilter(SampleFilter):
    """Mean of the last ``taps`` inputs per channel (a ring buffer and a running sum)."""

    def __init__(self, time_constant_s: float, dt_s: float) -> None:
        self.taps = max(1, round(time_constant_s / dt_s))
        self._ring: list[list[float]] = []
        self._sums: list[float] = []
        self._index = 0

    def reset(self, values: Sequence[float]) -> None:
        """Every past input equal to ``values``."""
        self._ring = [[float(v) for v in values] for _ in range(self.taps)]
        self._sums = [float(v) * self.taps for v in values]
        self._index = 0

    def step(self, values: Sequence[float]) -> list[float]:
        """Drop the oldest input, add this one, return the means."""
        oldest = self._ring[self._index]
        self._sums = sums = [s + x - o for s, x, o in zip(self._sums, values, oldest)]
        self._ring[self._index] = [float(x) for x in values]
        self._index = (self._index + 1) % self.taps
        scale = 1.0 / self.taps
        return [s * scale for s in sums]


#: Filters by kind: (T_ip [s], tick period [s]) -> a filter.
ACCEL_DECEL_FILTERS: dict[str, Callable[[float, float], SampleFilter]] = {
    "none": lambda time_constant_s, dt_s: PassThrough(),
    "exponential": ExponentialFilter,
    "linear": MovingAverageFilter,
}


def make_filter(config: AccelDecelConfig, dt_s: float) -> SampleFilter:
    """The filter of ``config`` at the tick period ``dt_s`` [s] (> 0)."""
    if not dt_s > 0.0:
        raise ConfigError(f"accel_decel: dt_s must be > 0, got {dt_s}")
    return ACCEL_DECEL_FILTERS[config.kind](config.time_constant_s, dt_s)


def filter_coefficients(config: AccelDecelConfig, dt_s: float) -> tuple[list[float], list[float]]:
    """``(b, a)`` of the filter for ``scipy.signal.lfilter`` (the same recursion as the per-sample step)."""
    built = make_filter(config, dt_s)
    if isinstance(built, ExponentialFilter):
        return [built.alpha], [1.0, built.alpha - 1.0]
    if isinstance(built, MovingAverageFilter):
        return [1.0 / built.taps] * built.taps, [1.0]
    return [1.0], [1.0]


class ReferenceFilter:
    """The filter on a stream of samples at tick times: the period from the first two times, fixed after.

    Times are compared in integer nanoseconds (the stamps' own unit), so the
    node and the engine, whose float seconds may differ in the last bit, get
    the same period and the same filter. A time at or before the previous one
    restarts the filter at that sample.
    """

    def __init__(self, config: AccelDecelConfig) -> None:
        self.config = config
        self._filter: SampleFilter | None = None
        self._first: list[float] | None = None
        self._last_ns = -1
        self._period_ns = 0

    def step(self, t_s: float, values: Sequence[float]) -> list[float]:
        """The filtered ``values`` at ``t_s`` [s] (position, velocity, acceleration of every axis, flat)."""
        if self.config.kind == "none":
            return list(values)
        t_ns = round(t_s * 1e9)
        if self._first is None or t_ns <= self._last_ns:
            self._first, self._filter, self._period_ns, self._last_ns = _at_rest(list(values)), None, 0, t_ns
            return list(self._first)
        if self._filter is None:
            self._period_ns = t_ns - self._last_ns
            self._filter = make_filter(self.config, self._period_ns * 1e-9)
            self._filter.reset(self._first)
        elif t_ns - self._last_ns != self._period_ns:
            raise ConfigError(f"accel_decel needs a fixed tick period {self._period_ns} ns, "
                              f"got {t_ns - self._last_ns} ns at t_s {t_s}")
        self._last_ns = t_ns
        return self._filter.step(values)


def _at_rest(values: list[float]) -> list[float]:
    """The first sample's positions with zero velocity and acceleration (flat [p…, v…, a…]): the filter at rest."""
    n = len(values) // 3
    return values[:n] + [0.0] * (len(values) - n)
