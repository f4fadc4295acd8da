"""Feed override on line: the planned profile time-scaled by a ratio that ramps within the axis limits (ROS-free).

The interpolator plans a profile ``p(τ)`` at the programmed feed. An override
ratio ``k(t)`` runs it at another pace, ``dτ/dt = k``, so the path stays the
programmed one and only the speed along it changes. The axis references become

    velocity      k v(τ) T
    acceleration  k² (a_t(τ) T + v(τ)² K) + k' v(τ) T

(``v``, ``a_t``, ``T``, ``K`` as in :mod:`cnc_contour_control.interpolation`).
A ratio that jumped would make ``k'`` unbounded, so :class:`OverrideFollower`
moves the applied ratio towards the requested one each tick only as far as
every axis's velocity and acceleration limits allow at the new sample (the
largest feasible step, found by bisection; zero step is always feasible
while ``k`` is within ``max_ratio``, see below). 0 is feed hold: the ratio
ramps down to 0 and the reference stops on the path; a later ratio > 0
resumes it from there.

For ratios above 1 the profile must be planned for them:
:func:`planning_limits` scales the limits the planner sees by
``1/max_ratio`` (velocity) and ``1/max_ratio²`` (acceleration), so
``k² |a_t T + v² K| <= a_max`` and ``k v |T| <= v_max`` for every
``k <= max_ratio``. With ``max_ratio = 1`` (the default) nothing changes.

Discrete steps: the servo sees sampled positions, and their differences
are not the analytic values where the ratio and the profile's phase change
in the same tick. A step is therefore taken only if the analytic velocity
and acceleration *and* the first and second differences of the positions
(this sample and the two before it) keep the limits, the accelerations
within ``acceleration_share`` of them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from cnc_contour_control.config import require_finite, require_non_negative
from cnc_contour_control.errors import ConfigError
from cnc_contour_control.interpolation import AxisLimits, Interpolator, ReferenceSample
from cnc_contour_control.params import check_ranges, param

_BISECTIONS = 40


@dataclass(frozen=True)
class OverrideConfig:
    """Options of the on-line feed override.

    Parameters
    ----------
    max_ratio : float
        The largest ratio applied, in [0, 2] (1.5 for a 0–150 % switch); the
        profile is planned for it (see :func:`planning_limits`).
    acceleration_share : float
        Share of each axis's acceleration limit the ramp may use, in (0, 1].
    """

    max_ratio: float = param(1.0, low=0.0, high=2.0, read_only=True,
                             description="largest feed override ratio applied (the profile is planned for it)")
    acceleration_share: float = param(0.98, low=0.05, high=1.0, read_only=True,
                                      description="share of each axis's acceleration limit a ratio ramp may use")

    def __post_init__(self) -> None:
        check_ranges(self)


def planning_limits(limits: AxisLimits, config: OverrideConfig) -> AxisLimits:
    """The limits to plan with so every ratio up to ``max_ratio`` keeps ``limits`` (unchanged for <= 1)."""
    scale = max(config.max_ratio, 1.0)
    if scale == 1.0:
        return limits
    return AxisLimits(tuple(v / scale for v in limits.max_velocity_m_s),
                      tuple(a / (scale * scale) for a in limits.max_acceleration_m_s2))


class OverrideFollower:
    """Advances an interpolator's profile at a feed override ratio that ramps within the axis limits.

    Parameters
    ----------
    interpolator : Interpolator
        Planned with :func:`planning_limits` of the machine's limits and ``config``.
    limits : AxisLimits
        The machine's axis limits (what the scaled reference must keep).
    config : OverrideConfig, optional
    """

    def __init__(self, interpolator: Interpolator, limits: AxisLimits, config: OverrideConfig | None = None) -> None:
        self.interpolator = interpolator
        self.config = config if config is not None else OverrideConfig()
        if limits.n_axes != interpolator.program.n_axes:
            raise ConfigError(f"limits must have one entry per program axis ({interpolator.program.n_axes}), "
                              f"got {limits.n_axes}")
        self._v_max = np.asarray(limits.max_velocity_m_s, dtype=float)
        self._a_max = np.asarray(limits.max_acceleration_m_s2, dtype=float) * self.config.acceleration_share
        self.reset()

    def reset(self, ratio: float = 1.0) -> None:
        """Back to the program start with the applied ratio at rest value ``ratio`` (the profile starts at rest)."""
        self.profile_time_s = 0.0
        self.ratio = self._clip(ratio)
        start = self.interpolator.sample(0.0).position_m
        self._last_m, self._before_m = start, start

    def _clip(self, ratio: float) -> float:
        return min(max(require_finite("override ratio", ratio), 0.0), self.config.max_ratio)

    def _scaled(self, ratio: float, dt_s: float) -> tuple[ReferenceSample, bool]:
        """The sample one tick ahead at ``ratio`` and whether it keeps the limits."""
        tau = min(self.profile_time_s + ratio * dt_s, self.interpolator.duration_s)
        base = self.interpolator.sample(tau)
        rate = (ratio - self.ratio) / dt_s
        velocity = ratio * base.velocity_m_s
        acceleration = (ratio * ratio) * base.acceleration_m_s2 + rate * base.velocity_m_s
        step_m = base.position_m - self._last_m
        differenced = (step_m - (self._last_m - self._before_m)) / (dt_s * dt_s)
        ok = bool(np.all(np.abs(velocity) <= self._v_max) and np.all(np.abs(step_m) <= self._v_max * dt_s)
                  and np.all(np.abs(acceleration) <= self._a_max) and np.all(np.abs(differenced) <= self._a_max))
        return replace(base, velocity_m_s=velocity, acceleration_m_s2=acceleration, feed_m_s=ratio * base.feed_m_s,
                       profile_time_s=tau, feed_override_ratio=ratio), ok

    def _largest_step(self, target: float, dt_s: float) -> tuple[float, ReferenceSample]:
        """The ratio nearest ``target`` on the way from the current one that keeps the limits, and its sample."""
        sample, ok = self._scaled(target, dt_s)
        if ok:
            return target, sample
        feasible, infeasible = self.ratio, target
        best = self._scaled(feasible, dt_s)[0]
        for _ in range(_BISECTIONS):
            middle = 0.5 * (feasible + infeasible)
            candidate, ok = self._scaled(middle, dt_s)
            if ok:
                feasible, best = middle, candidate
            else:
                infeasible = middle
        return feasible, best

    def advance(self, dt_s: float, requested_ratio: float) -> ReferenceSample:
        """One tick of ``dt_s`` towards ``requested_ratio`` (clipped to [0, max_ratio]); the new reference.

        The returned sample's ``feed_override_ratio`` is the ratio applied.
        ``dt_s = 0`` (the first tick) returns the current sample unchanged.
        """
        dt = require_non_negative("dt_s", dt_s)
        target = self._clip(requested_ratio)
        if dt == 0.0:
            base = self.interpolator.sample(self.profile_time_s)
            return replace(base, velocity_m_s=self.ratio * base.velocity_m_s,
                           acceleration_m_s2=self.ratio ** 2 * base.acceleration_m_s2,
                           feed_m_s=self.ratio * base.feed_m_s, feed_override_ratio=self.ratio)
        ratio, sample = self._largest_step(target, dt)
        self.ratio, self.profile_time_s = ratio, sample.profile_time_s
        self._before_m, self._last_m = self._last_m, sample.position_m
        return sample


def hold_distance_m(speed_m_s: float, deceleration_m_s2: float) -> float:
    """The path length a feed hold from ``speed_m_s`` needs at ``deceleration_m_s2`` (a bound for tests/docs)."""
    if deceleration_m_s2 <= 0.0 or not math.isfinite(deceleration_m_s2):
        raise ConfigError(f"deceleration_m_s2 must be > 0, got {deceleration_m_s2}")
    return speed_m_s * speed_m_s / (2.0 * deceleration_m_s2)
