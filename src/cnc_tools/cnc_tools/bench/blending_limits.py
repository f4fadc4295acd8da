"""The blending benches' limits, planner options and sampled checks (shared by :mod:`cnc_tools.bench.blending`,
its override sweep, its dense-CAM stream and the jerk bench).

Paper 000's limits (2000 mm/min, 250 mm/s² per axis), a machine tool's jerk limit (:data:`MAX_JERK_M_S3`),
the planner options the bench found best (:data:`BEST_OPTIONS`, the shipped defaults), and the per-axis
velocity, acceleration and jerk ratios of a sampled reference, each the larger of the analytic value and the
finite difference.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig

TOLERANCE_MM = 0.01
MAX_VELOCITY_M_S = 2000.0 / 60000.0
MAX_ACCELERATION_M_S2 = 0.25
#: A machine tool's jerk limit, m/s³: the acceleration limit reached in 25 ms.
MAX_JERK_M_S3 = MAX_ACCELERATION_M_S2 / 0.025
#: Sample period of the checks, s. The finite-difference acceleration's rounding floor is about
#: 4 ulp(position) / dt**2: 1.4e-9 of 250 mm/s^2 at 0.2 ms, 6e-11 at 1 ms (paper 000 samples at 10 ms).
SAMPLE_S = 1e-3
#: The third difference of positions is taken every ``JERK_STRIDE`` samples: its rounding floor,
#: 4 ulp(position) / dt**3, is 3e-9 of 10 m/s³ at 1 ms and 4e-11 at 4 ms.
JERK_STRIDE = 4
LIMIT_GOAL = 1.0 + 1e-9


def planner_takes_jerk() -> bool:
    """Whether :class:`AxisLimits` takes a per-axis jerk limit (``max_jerk_m_s3``)."""
    return "max_jerk_m_s3" in {field.name for field in dataclasses.fields(AxisLimits)}


def limits_for(program: Program, jerk: bool = False) -> AxisLimits:
    """Paper 000's limits on every axis of ``program``; with ``jerk``, :data:`MAX_JERK_M_S3` if the planner takes it."""
    n = program.n_axes
    values: dict[str, Any] = {"max_velocity_m_s": (MAX_VELOCITY_M_S,) * n,
                              "max_acceleration_m_s2": (MAX_ACCELERATION_M_S2,) * n}
    if jerk and planner_takes_jerk():
        values["max_jerk_m_s3"] = (MAX_JERK_M_S3,) * n
    return AxisLimits(**values)


#: The planner options the bench found best, shipped as :class:`InterpolatorConfig`'s defaults
#: (``test_bench_blending`` holds them equal): arcs with the combined acceleration budget and 80 % of it for the
#: centripetal part (the split budget's 50 % left the arc chain at 1.24x toppra), 8 speed bands per arc (16 and 64
#: gain under 0.1 %).
BEST_OPTIONS: dict[str, Any] = {"arc_combined_budget": True, "arc_centripetal_fraction": 0.8, "arc_speed_bands": 8}


def bench_config(tolerance_mm: float = TOLERANCE_MM) -> InterpolatorConfig:
    """The planner options of the bench (:data:`BEST_OPTIONS`) with the path tolerance."""
    return InterpolatorConfig(path_tolerance_mm=tolerance_mm, **BEST_OPTIONS)


def sampled_ratios(position_m: np.ndarray, velocity_m_s: np.ndarray, acceleration_m_s2: np.ndarray, dt_s: float,
                   n_axes: int) -> dict[str, np.ndarray]:
    """Worst velocity, acceleration and jerk over their limits per axis of a reference sampled every ``dt_s``.

    Arrays ``(M, n_axes)``: positions (m), velocities (m/s), accelerations (m/s²). Velocity: the larger of
    ``|v|`` and ``|Δp| / dt``; acceleration: of ``|a|`` and ``|Δ²p| / dt²``; jerk: of ``|Δa| / dt`` and
    ``|Δ³p| / (s dt)³`` over every ``s = JERK_STRIDE``-th sample. A finite difference is a positive-weight
    average of the derivative over its span, so each is at most the derivative's largest value.
    """
    coarse = position_m[::JERK_STRIDE]
    velocity = np.vstack([np.abs(velocity_m_s), np.abs(np.diff(position_m, axis=0)) / dt_s])
    acceleration = np.vstack([np.abs(acceleration_m_s2), np.abs(np.diff(position_m, 2, axis=0)) / dt_s**2])
    jerk = np.vstack([np.abs(np.diff(acceleration_m_s2, axis=0)) / dt_s,
                      np.abs(np.diff(coarse, 3, axis=0)) / (JERK_STRIDE * dt_s) ** 3, np.zeros((1, n_axes))])
    return {"velocity_ratio": velocity.max(axis=0) / MAX_VELOCITY_M_S,
            "acceleration_ratio": acceleration.max(axis=0) / MAX_ACCELERATION_M_S2,
            "jerk_ratio": jerk.max(axis=0) / MAX_JERK_M_S3}


def reference_ratios(interpolator: Interpolator, dt_s: float = SAMPLE_S) -> dict[str, np.ndarray]:
    """:func:`sampled_ratios` of ``interpolator``'s profile sampled every ``dt_s`` from 3 samples before its start
    to 3 after its end."""
    trajectory = interpolator.sample_array(np.arange(-3 * dt_s, interpolator.duration_s + 3 * dt_s, dt_s))
    return sampled_ratios(trajectory.position_m, trajectory.velocity_m_s, trajectory.acceleration_m_s2, dt_s,
                          interpolator.limits.n_axes)


def limit_ratios(interpolator: Interpolator, dt_s: float = SAMPLE_S) -> tuple[np.ndarray, np.ndarray]:
    """Worst velocity and acceleration ratio to ``interpolator.limits`` per axis, ``(n_axes,)`` each.

    The worst of the analytic value and the finite difference of positions sampled every ``dt_s``.
    """
    times = np.arange(-3 * dt_s, interpolator.duration_s + 3 * dt_s, dt_s)
    trajectory = interpolator.sample_array(times)
    v_max = np.asarray(interpolator.limits.max_velocity_m_s)
    a_max = np.asarray(interpolator.limits.max_acceleration_m_s2)
    velocity = np.vstack([np.abs(trajectory.velocity_m_s), np.abs(np.diff(trajectory.position_m, axis=0)) / dt_s])
    acceleration = np.vstack([np.abs(trajectory.acceleration_m_s2),
                              np.abs(np.diff(trajectory.position_m, 2, axis=0)) / dt_s**2])
    return velocity.max(axis=0) / v_max, acceleration.max(axis=0) / a_max


def worst_deviation_m(interpolator: Interpolator, dt_s: float = SAMPLE_S) -> float:
    """Largest distance of the sampled reference from the programmed path, m."""
    trajectory = interpolator.sample_array(np.arange(0.0, interpolator.duration_s + dt_s, dt_s))
    return float(np.max(interpolator.blended.local_deviation_m(trajectory.position_m, trajectory.segment_index)))
