"""Curvature-continuous corners of the jerk-limited planner: a line-line corner passed at speed.

A corner at point ``P`` between unit directions ``u1`` (in) and ``u2`` (out), turning by ``θ``, is passed at
the speed ``v`` in a time ``τ`` by blending the velocity, not the geometry:

    x = t / τ,  σ(x) = 3x² - 2x³,  Σ(x) = x³ - x⁴/2
    velocity      v (u1 + Δu σ(x))                          (Δu = u2 - u1)
    position      P - d u1 + v τ (x u1 + Δu Σ(x))           (d = v τ / 2: the trim of each line)
    acceleration  v Δu 6x(1 - x) / τ                        (0 at both ends: curvature 0 there, G2)
    jerk          v Δu (6 - 12x) / τ²

It leaves the first line ``d`` before ``P`` and joins the second ``d`` after it. Per axis
``|a_j| <= 1.5 v |Δu_j| / τ`` and ``|j_j| <= 6 v |Δu_j| / τ²``; the speed never exceeds ``v`` (a convex
combination of unit vectors). Its largest distance from the two lines is ``(3 d / 16) sin θ`` at ``x = 1/2``
(the first half's distance to the first line grows with ``x``, the second half mirrors it), so the corner
keeps a path tolerance ``P_tol`` with ``d <= 16 P_tol / (3 sin θ)``. :func:`corner_speed_m_s` gives the
highest ``v`` with ``τ`` the shortest the axes allow, ``d`` within that bound and within half of each line.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cnc_contour_control.motion.points import FloatArray

#: Turns within this of a reversal stop (rad): the blend would leave the line and come back on it.
REVERSAL_MARGIN_RAD = 1.0e-6


@dataclass(frozen=True)
class CornerAxes:
    """Per-axis limits of a corner: acceleration (m/s²) and jerk (m/s³), ``(n_axes,)`` each."""

    max_acceleration_m_s2: FloatArray
    max_jerk_m_s3: FloatArray


def corner_time_s(speed_m_s: float, change: FloatArray, axes: CornerAxes) -> float:
    """The shortest ``τ`` (s) at ``speed_m_s`` with every axis within its limits; ``change`` is ``|Δu_j|``."""
    moving = change > 0.0
    if speed_m_s <= 0.0 or not moving.any():
        return 0.0
    accel = 1.5 * speed_m_s * change[moving] / axes.max_acceleration_m_s2[moving]
    jerk = np.sqrt(6.0 * speed_m_s * change[moving] / axes.max_jerk_m_s3[moving])
    return float(max(accel.max(), jerk.max()))


def corner_speed_m_s(turn_rad: float, change: FloatArray, trim_max_m: float, tolerance_m: float,
                     axes: CornerAxes) -> float:
    """The highest corner speed (m/s) whose trim ``v τ(v) / 2`` is within ``trim_max_m`` and the tolerance."""
    if tolerance_m <= 0.0 or turn_rad >= math.pi - REVERSAL_MARGIN_RAD:
        return 0.0
    sine = math.sin(turn_rad)
    trim = trim_max_m if sine <= 0.0 else min(trim_max_m, 16.0 * tolerance_m / (3.0 * sine))
    moving = change > 0.0
    if not moving.any():
        return math.inf
    c, a, j = change[moving], axes.max_acceleration_m_s2[moving], axes.max_jerk_m_s3[moving]
    by_accel = np.sqrt(trim * a / (0.75 * c))              # d = 0.75 v² c / a
    by_jerk = (2.0 * trim / np.sqrt(6.0 * c / j)) ** (2.0 / 3.0)   # d = 0.5 v^1.5 sqrt(6 c / j)
    return float(min(by_accel.min(), by_jerk.min()))


@dataclass(frozen=True)
class Corner:
    """A corner passed at ``speed_m_s`` in ``duration_s``: at ``point_m`` from ``unit_in`` to ``unit_out``."""

    point_m: FloatArray
    unit_in: FloatArray
    unit_out: FloatArray
    speed_m_s: float
    duration_s: float

    @property
    def trim_m(self) -> float:
        """Length taken from each line, m."""
        return 0.5 * self.speed_m_s * self.duration_s

    def evaluate(self, times_s: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Share ``x`` of the corner, position (m), velocity (m/s), acceleration (m/s²) ``(M, n_axes)`` at local
        times ``times_s`` (s, clipped to ``[0, duration_s]``)."""
        x = np.clip(np.asarray(times_s, dtype=float).reshape(-1) / self.duration_s, 0.0, 1.0)[:, None]
        change = self.unit_out - self.unit_in
        v, tau = self.speed_m_s, self.duration_s
        position = self.point_m - self.trim_m * self.unit_in + v * tau * (x * self.unit_in + change * (x**3 - x**4 / 2))
        velocity = v * (self.unit_in + change * (3.0 * x**2 - 2.0 * x**3))
        acceleration = v * change * (6.0 * x * (1.0 - x)) / tau
        return x[:, 0], position, velocity, acceleration
