"""A jerk-limited (S-curve) time law along a path, from rest to rest.

Over a length ``L`` (m) with path limits ``V`` (m/s), ``A`` (m/s²) and ``J`` (m/s³) the speed rises
from rest to a peak ``v_p <= V`` and falls back to rest in seven phases of constant jerk
``+J, 0, -J, 0, -J, 0, +J``: the acceleration ramps (never steps), and is 0 at both ends. Durations:

    T_j = min(A / J, sqrt(v_p / J))      (jerk phases; peak acceleration a_p = J T_j)
    T_a = v_p / a_p - T_j                (constant-acceleration phase)
    T_c = (L - v_p (2 T_j + T_a)) / v_p  (cruise)

``v_p`` is ``V`` where the ramps fit in ``L``, else the speed whose ramps take all of it (closed form).
Every value is within its limit exactly; :meth:`SCurve.evaluate` gives ``s, v, a, j`` at any times.
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


def peak_speed_m_s(length_m: float, speed_m_s: float, accel_m_s2: float, jerk_m_s3: float) -> float:
    """The highest speed (m/s, <= ``speed_m_s``) whose rise from rest and fall back to rest fit in ``length_m``."""
    if 2.0 * ramp_length_m(speed_m_s, accel_m_s2, jerk_m_s3) <= length_m:
        return speed_m_s
    triangular = (0.5 * length_m * math.sqrt(jerk_m_s3)) ** (2.0 / 3.0)
    if triangular * jerk_m_s3 <= accel_m_s2 * accel_m_s2:
        return min(triangular, speed_m_s)
    ratio = accel_m_s2 / jerk_m_s3
    return min(0.5 * accel_m_s2 * (math.sqrt(ratio * ratio + 4.0 * length_m / accel_m_s2) - ratio), speed_m_s)


@dataclass(frozen=True)
class SCurve:
    """The rest-to-rest S-curve over ``length_m`` (m) under ``speed_m_s``, ``accel_m_s2``, ``jerk_m_s3`` (> 0).

    ``durations_s`` (7,) and ``jerks_m_s3`` (7,) are its phases; ``duration_s`` their sum.
    """

    length_m: float
    speed_m_s: float
    accel_m_s2: float
    jerk_m_s3: float
    durations_s: FloatArray = field(init=False, repr=False)
    jerks_m_s3: FloatArray = field(init=False, repr=False)
    peak_m_s: float = field(init=False)

    def __post_init__(self) -> None:
        for name in ("length_m", "speed_m_s", "accel_m_s2", "jerk_m_s3"):
            require_positive(name, getattr(self, name), "SCurve")
        peak = peak_speed_m_s(self.length_m, self.speed_m_s, self.accel_m_s2, self.jerk_m_s3)
        ramp = min(self.accel_m_s2 / self.jerk_m_s3, math.sqrt(peak / self.jerk_m_s3))
        flat = max(peak / (self.jerk_m_s3 * ramp) - ramp, 0.0)
        cruise = max(self.length_m - 2.0 * ramp_length_m(peak, self.accel_m_s2, self.jerk_m_s3), 0.0) / peak
        j = self.jerk_m_s3
        object.__setattr__(self, "durations_s", np.array([ramp, flat, ramp, cruise, ramp, flat, ramp]))
        object.__setattr__(self, "jerks_m_s3", np.array([j, 0.0, -j, 0.0, -j, 0.0, j]))
        object.__setattr__(self, "peak_m_s", peak)
        starts = [(0.0, 0.0, 0.0)]
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

        Before 0 the start (rest at 0), after :attr:`duration_s` the end (rest at ``length_m``).
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
        v, a = np.where(end, 0.0, np.clip(v, 0.0, self.speed_m_s)), np.where(end, 0.0, a)
        return s, v, np.clip(a, -self.accel_m_s2, self.accel_m_s2), jerk

    _starts: FloatArray = field(init=False, repr=False, compare=False)
    _times: FloatArray = field(init=False, repr=False, compare=False)


def _advance(s0: float, v0: float, a0: float, jerk: float, dt: float) -> tuple[float, float, float]:
    """Path length, speed and acceleration after ``dt`` (s) of constant ``jerk`` from ``(s0, v0, a0)``."""
    return (s0 + v0 * dt + a0 * dt * dt / 2.0 + jerk * dt ** 3 / 6.0, v0 + a0 * dt + jerk * dt * dt / 2.0,
            a0 + jerk * dt)
