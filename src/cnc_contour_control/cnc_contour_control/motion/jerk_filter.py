"""The FIR jerk filter: a moving average of ``n`` samples after interpolation (ROS-free).

A reference sampled every ``T`` whose every axis keeps ``|Δp| <= vmax T`` and ``|Δ²p| <= amax T²`` keeps both
through a moving average of ``n`` samples (an average of bounded values is bounded), and its jerk becomes

    Δ³p_f(k) / T³ = (Δ²p(k) - Δ²p(k - n)) / (n T³),   |Δ³p_f| / T³ <= 2 amax / (n T)

so ``n = ceil(2 amax_j / (jmax_j T))`` keeps axis ``j``'s jerk limit. :func:`filter_taps` takes the largest ``n``
of the axes and every axis gets it: the filtered point is then a convex combination of points of the path (on a
line it stays on the line), which a different ``n`` per axis would not keep. The filter delays the reference by
``(n - 1) T / 2`` and lengthens the motion by ``(n - 1) T``.

:class:`MovingAverage` is the per-sample form (a ring buffer and a running sum, summed afresh at every wrap so
that rounding cannot drift); :func:`moving_average_rows` the same sums for many samples at once.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.core.config import require_positive
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.axis_limits import AxisLimits

FloatArray = NDArray[np.float64]
#: Most taps a filter takes (10 s at 1 ms).
MAX_TAPS = 10_000


def filter_taps(limits: AxisLimits, period_s: float) -> int:
    """Taps ``n = max_j ceil(2 amax_j / (jmax_j T))`` that keep every axis's jerk limit at period ``period_s`` (s).

    Raises :class:`ConfigError` when ``limits`` has no jerk limit or ``n`` exceeds :data:`MAX_TAPS`.
    """
    period = require_positive("jerk_filter_period_s", period_s)
    if limits.max_jerk_m_s3 is None:
        raise ConfigError("max_jerk_m_s3 must be set for the FIR jerk filter, got None")
    ratio = max(2.0 * a / (j * period) for a, j in zip(limits.max_acceleration_m_s2, limits.max_jerk_m_s3))
    taps = max(1, math.ceil(ratio * (1.0 - 1e-12)))
    if taps > MAX_TAPS:
        raise ConfigError(f"jerk filter taps 2 max_acceleration / (max_jerk jerk_filter_period_s) must be <= "
                          f"{MAX_TAPS}, got {taps} (period {period} s)")
    return taps


class MovingAverage:
    """Mean of the last ``taps`` samples of ``channels`` values (``reset`` to rest, then ``step`` per sample).

    Parameters
    ----------
    taps : int
        Samples averaged, in [1, :data:`MAX_TAPS`].
    channels : int
        Values per sample, >= 1.
    """

    def __init__(self, taps: int, channels: int) -> None:
        if isinstance(taps, bool) or not isinstance(taps, int) or not 1 <= taps <= MAX_TAPS:
            raise ConfigError(f"taps must be a whole number in [1, {MAX_TAPS}], got {taps!r}")
        if isinstance(channels, bool) or not isinstance(channels, int) or channels < 1:
            raise ConfigError(f"channels must be a whole number >= 1, got {channels!r}")
        self.taps, self.channels = taps, channels
        self.reset([0.0] * channels)

    def reset(self, values: Sequence[float]) -> None:
        """At rest at ``values``: every past sample equal to them."""
        row = self._row(values)
        self._ring = [list(row) for _ in range(self.taps)]
        self._sums = [v * self.taps for v in row]
        self._index = 0

    def _row(self, values: Sequence[float]) -> list[float]:
        row = [float(v) for v in values]
        if len(row) != self.channels:
            raise ConfigError(f"values must have {self.channels} channels, got {len(row)}")
        return row

    def step(self, values: Sequence[float]) -> list[float]:
        """Drop the oldest sample, add ``values``; the means (a new list of ``channels``)."""
        row = self._row(values)
        oldest = self._ring[self._index]
        self._ring[self._index] = row
        self._index = (self._index + 1) % self.taps
        if self._index == 0:
            self._sums = [math.fsum(column) for column in zip(*self._ring)]
        else:
            self._sums = [s + x - o for s, x, o in zip(self._sums, row, oldest)]
        scale = 1.0 / self.taps
        return [s * scale for s in self._sums]


def moving_average_rows(rows: FloatArray, taps: int) -> FloatArray:
    """Means of every ``taps`` consecutive rows: ``(M + taps - 1, C)`` in, ``(M, C)`` out (output ``i``: rows
    ``i .. i + taps - 1``), summed slice by slice (no cumulative sum, whose rounding grows with ``M``)."""
    x = np.asarray(rows, dtype=float)
    count = x.shape[0] - taps + 1
    if taps < 1 or count < 1:
        raise ConfigError(f"rows must have at least taps = {taps} rows, got {x.shape[0]}")
    total = x[:count].copy()
    for i in range(1, taps):
        total += x[i:i + count]
    return total / taps
