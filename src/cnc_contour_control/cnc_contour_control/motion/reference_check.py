"""A program's reference sampled at a period, and its velocity, acceleration and jerk over the axis limits.

The check differentiates the sampled positions: the ``k``-th difference over every ``s``-th sample,
``|Δᵏp| / (s T)ᵏ``, with the smallest stride ``s`` whose rounding floor ``2ᵏ ulp(max |p|) / (s T)ᵏ`` is at most
``1e-10`` of the smallest limit (``s = 1`` for velocity and acceleration at 1 ms on today's limits; a few samples
for jerk). A finite difference is a positive-weight average of the derivative over its span, so none exceeds
the derivative's largest value: a ratio over ``1 + 1e-9`` is a real excess, not a sampling artefact.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnc_contour_control.core.config import require_positive
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.points import FloatArray
from cnc_contour_control.motion.reference_types import ReferenceTrajectory

#: Largest rounding floor of a finite difference, as a share of the limit it is compared with.
ROUNDING_SHARE = 1.0e-10

def sample_reference(program: Program, limits: AxisLimits, config: InterpolatorConfig | None = None,
                     period_s: float = 1.0e-3) -> tuple[Interpolator, ReferenceTrajectory]:
    """The planner of ``program`` and its reference every ``period_s`` (s), 3 samples before 0 to 3 past the end.

    Whichever mode ``limits`` selects (jerk-limited with ``max_jerk_m_s3``).
    """
    period = require_positive("period_s", period_s)
    interpolator = Interpolator(program, limits, config)
    times = np.arange(-3.0 * period, interpolator.duration_s + 3.0 * period, period)
    return interpolator, interpolator.sample_array(times)


@dataclass(frozen=True)
class LimitRatios:
    """Largest ``|v_j| / vmax_j``, ``|a_j| / amax_j``, ``|j_j| / jmax_j`` per axis, ``(n_axes,)`` each.

    ``jerk`` is all NaN where the limits have no jerk limit.
    """

    velocity: FloatArray
    acceleration: FloatArray
    jerk: FloatArray

    def worst(self) -> float:
        """The largest ratio of the three (jerk left out where NaN)."""
        return float(np.nanmax(np.concatenate([self.velocity, self.acceleration, self.jerk])))


def limit_ratios(position_m: FloatArray, period_s: float, limits: AxisLimits) -> LimitRatios:
    """:class:`LimitRatios` of positions ``(M, n_axes)`` (m) sampled every ``period_s`` (s), by finite differences."""
    p = np.asarray(position_m, dtype=float)
    ulp = float(np.spacing(np.abs(p).max(initial=1.0)))
    out = [np.full(p.shape[1], np.nan)] * 3
    for order, limit in enumerate((limits.max_velocity_m_s, limits.max_acceleration_m_s2, limits.max_jerk_m_s3), 1):
        if limit is None:
            continue
        floor = 2.0 ** order * ulp / (ROUNDING_SHARE * min(limit))
        stride = max(1, math.ceil(floor ** (1.0 / order) / period_s))
        worst = np.abs(np.diff(p[::stride], order, axis=0)).max(axis=0, initial=0.0) / (stride * period_s) ** order
        out[order - 1] = worst / np.asarray(limit)
    return LimitRatios(*out)
