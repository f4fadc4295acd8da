"""A jerk-limited (S-curve) time law along a path piece, from an entry speed to an exit speed.

Over a length ``L`` (m) with path limits ``V`` (m/s), ``A`` (m/s²) and ``J`` (m/s³) the speed rises
from the entry speed ``v_0`` to a peak ``v_p <= V``, cruises, and falls to the exit speed ``v_1`` in seven
phases of constant jerk ``+J, 0, -J, 0, -J, 0, +J``: the acceleration ramps (never steps) and is 0 at both
ends. A change of speed by ``Δ`` takes (:func:`ramp_time_s`)

    T_j = min(A / J, sqrt(Δ / J))        (each jerk phase; peak acceleration J T_j)
    T_a = Δ / (J T_j) - T_j              (constant-acceleration phase)

and ``(v_0 + v_p) / 2 (2 T_j + T_a)`` of length (:func:`change_length_m`). ``v_p`` is ``V`` where both changes
fit in ``L``, else the highest speed whose changes take all of it (closed form from rest to rest, bisection
otherwise). Every value is within its limit; :meth:`SCurve.evaluate` gives ``s, v, a, j`` at any times.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnc_contour_control.core.config import require_positive

FloatArray = NDArray[np.float64]


def ramp_length_m(speed_m_s: float, accel_m_s2: float, jerk_m_s3: float) -> float:
    """Distance (m) an S-curve takes from rest to ``speed_m_s`` (and from it back to rest)."""
    if speed_m_s * jerk_m_s3 <= accel_m_s2 * accel_m_s2:
        return speed_m_s * math.sqrt(speed_m_s / jerk_m_s3)
    return 0.5 * speed_m_s * (speed_m_s / accel_m_s2 + accel_m_s2 / jerk_m_s3)


def ramp_time_s(change_m_s: float, accel_m_s2: float, jerk_m_s3: float) -> float:
    """Time (s) an S-curve takes to change the speed by ``change_m_s`` (m/s, either sign)."""
    change = abs(change_m_s)
    if change * jerk_m_s3 <= accel_m_s2 * accel_m_s2:
        return 2.0 * math.sqrt(change / jerk_m_s3)
    return change / accel_m_s2 + accel_m_s2 / jerk_m_s3


def change_length_m(from_m_s: float, to_m_s: float, accel_m_s2: float, jerk_m_s3: float) -> float:
    """Distance (m) an S-curve takes from speed ``from_m_s`` to ``to_m_s`` (its mean speed is their mean)."""
    return 0.5 * (from_m_s + to_m_s) * ramp_time_s(to_m_s - from_m_s, accel_m_s2, jerk_m_s3)


def reachable_m_s(from_m_s: float, length_m: float, cap_m_s: float, accel_m_s2: float, jerk_m_s3: float) -> float:
    """The highest speed (m/s, in ``[from_m_s, cap_m_s]``) an S-curve reaches from ``from_m_s`` within ``length_m``."""
    if cap_m_s <= from_m_s or change_length_m(from_m_s, cap_m_s, accel_m_s2, jerk_m_s3) <= length_m:
        return cap_m_s
    low, high = from_m_s, cap_m_s
    for _ in range(60):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if change_length_m(from_m_s, middle, accel_m_s2, jerk_m_s3) <= length_m \
            else (low, middle)
    return low


def peak_speed_m_s(length_m: float, speed_m_s: float, accel_m_s2: float, jerk_m_s3: float,
                   entry_m_s: float = 0.0, exit_m_s: float = 0.0) -> float:
    """The highest speed (m/s, <= ``speed_m_s``) whose rise from the entry speed and fall to the exit speed fit
    in ``length_m`` (entry and exit reachable from each other within it)."""
    def length(peak: float) -> float:
        return (change_length_m(entry_m_s, peak, accel_m_s2, jerk_m_s3)
                + change_length_m(peak, exit_m_s, accel_m_s2, jerk_m_s3))
    if length(speed_m_s) <= length_m:
        return speed_m_s
    if entry_m_s == 0.0 and exit_m_s == 0.0:
        return _rest_to_rest_peak_m_s(length_m, speed_m_s, accel_m_s2, jerk_m_s3)
    low = max(entry_m_s, exit_m_s)
    high = speed_m_s
    for _ in range(60):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if length(middle) <= length_m else (low, middle)
    return low


def _rest_to_rest_peak_m_s(length_m: float, speed_m_s: float, accel_m_s2: float, jerk_m_s3: float) -> float:
    triangular = (0.5 * length_m * math.sqrt(jerk_m_s3)) ** (2.0 / 3.0)
    if triangular * jerk_m_s3 <= accel_m_s2 * accel_m_s2:
        return min(triangular, speed_m_s)
    ratio = accel_m_s2 / jerk_m_s3
    return min(0.5 * accel_m_s2 * (math.sqrt(ratio * ratio + 4.0 * length_m / accel_m_s2) - ratio), speed_m_s)


@dataclass(frozen=True)
class SCurve:
    """The S-curve over ``length_m`` (m) under ``speed_m_s``, ``accel_m_s2``, ``jerk_m_s3`` (> 0), from
    ``entry_m_s`` to ``exit_m_s`` (>= 0, reachable from each other within the length; default: rest to rest).

    ``durations_s`` (7,) and ``jerks_m_s3`` (7,) are its phases; ``duration_s`` their sum.
    """

    length_m: float
    speed_m_s: float
    accel_m_s2: float
    jerk_m_s3: float
    entry_m_s: float = 0.0
    exit_m_s: float = 0.0
    durations_s: FloatArray = field(init=False, repr=False)
    jerks_m_s3: FloatArray = field(init=False, repr=False)
    peak_m_s: float = field(init=False)

    def __post_init__(self) -> None:
        for name in ("speed_m_s", "accel_m_s2", "jerk_m_s3"):
            require_positive(name, getattr(self, name), "SCurve")
        a, j = self.accel_m_s2, self.jerk_m_s3
        peak = peak_speed_m_s(self.length_m, self.speed_m_s, a, j, self.entry_m_s, self.exit_m_s)
        rest = self.length_m - change_length_m(self.entry_m_s, peak, a, j) - change_length_m(peak, self.exit_m_s, a, j)
        cruise = max(rest, 0.0) / peak if peak > 0.0 else 0.0
        up, down = _change_phases(peak - self.entry_m_s, a, j), _change_phases(peak - self.exit_m_s, a, j)
        object.__setattr__(self, "durations_s", np.array([*up, cruise, *down]))
        object.__setattr__(self, "jerks_m_s3", np.array([j, 0.0, -j, 0.0, -j, 0.0, j]))
        object.__setattr__(self, "peak_m_s", peak)
        starts = [(0.0, self.entry_m_s, 0.0)]
        for duration, jerk in zip(self.durations_s.tolist(), self.jerks_m_s3.tolist()):
            starts.append(_advance(*starts[-1], jerk, duration))
        object.__setattr__(self, "_starts", np.array(starts))
        object.__setattr__(self, "_times", np.concatenate([[0.0], np.cumsum(self.durations_s)]))

    @property
    def duration_s(self) -> float:
        """Time from rest to rest, s."""
        return float(self._times[-1])

    def evaluate(self, times_s: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Path length (m), speed (m/s), acceleration (m/s²) and jerk (m/s³) at ``times_s`` (s, shape ``(M,)``).

        Before 0 the start (0 at the entry speed), after :attr:`duration_s` the end (``length_m`` at the exit
        speed); acceleration and jerk 0 outside.
        """
        t = np.clip(np.asarray(times_s, dtype=float).reshape(-1), 0.0, self.duration_s)
        k = np.clip(np.searchsorted(self._times, t, side="right") - 1, 0, 6)
        dt = t - self._times[k]
        s0, v0, a0 = self._starts[k, 0], self._starts[k, 1], self._starts[k, 2]
        jerk = self.jerks_m_s3[k]
        s = s0 + v0 * dt + a0 * dt * dt / 2.0 + jerk * dt ** 3 / 6.0
        v = v0 + a0 * dt + jerk * dt * dt / 2.0
        a = a0 + jerk * dt
        end = t >= self.duration_s
        jerk = np.where(end, 0.0, jerk)
        s = np.where(end, self.length_m, np.clip(s, 0.0, self.length_m))
        v, a = np.where(end, self.exit_m_s, np.clip(v, 0.0, self.speed_m_s)), np.where(end, 0.0, a)
        return s, v, np.clip(a, -self.accel_m_s2, self.accel_m_s2), jerk

    _starts: FloatArray = field(init=False, repr=False, compare=False)
    _times: FloatArray = field(init=False, repr=False, compare=False)


def _change_phases(change_m_s: float, accel_m_s2: float, jerk_m_s3: float) -> tuple[float, float, float]:
    """Durations (s) of the jerk, constant-acceleration and jerk phases of a speed change by ``change_m_s`` >= 0."""
    if change_m_s <= 0.0:
        return 0.0, 0.0, 0.0
    ramp = min(accel_m_s2 / jerk_m_s3, math.sqrt(change_m_s / jerk_m_s3))
    return ramp, max(change_m_s / (jerk_m_s3 * ramp) - ramp, 0.0), ramp


def _advance(s0: float, v0: float, a0: float, jerk: float, dt: float) -> tuple[float, float, float]:
    """Path length, speed and acceleration after ``dt`` (s) of constant ``jerk`` from ``(s0, v0, a0)``."""
    return (s0 + v0 * dt + a0 * dt * dt / 2.0 + jerk * dt ** 3 / 6.0, v0 + a0 * dt + jerk * dt * dt / 2.0,
            a0 + jerk * dt)
