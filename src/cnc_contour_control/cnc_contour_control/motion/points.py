"""What every contour segment shares: point arrays, tolerances, feeds (SI, one entry per machine axis)."""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnc_contour_control.core.config import require_finite, require_positive
from cnc_contour_control.core.errors import ConfigError, ProgramError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Two points closer than this are the same point (contiguity, full circles), m.
POSITION_TOLERANCE_M = 1.0e-6
#: Largest allowed difference between an arc's end and start radius, m (as LinuxCNC: 0.002 mm).
RADIUS_TOLERANCE_M = 2.0e-6
#: Shortest segment (and smallest radius) accepted, m.
MIN_LENGTH_M = 1.0e-9
#: Largest coordinate, length or radius a program may give, mm (100 m: beyond the largest machine tool), so a
#: wrong value is refused by its own name, not by a point computed from it.
MAX_EXTENT_MM = 1.0e5
#: Smallest radius, length or leg a program may give, mm (1 µm, the position tolerance: below, no contour).
MIN_EXTENT_MM = 1.0e-3
#: Slowest programmed feed, mm/min (0.6 mm an hour): slower, a program takes longer than a run may last.
MIN_FEED_MM_MIN = 1.0e-2
TWO_PI = 2.0 * math.pi
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def as_point(name: str, value: ArrayLike, n_axes: int | None = None) -> FloatArray:
    """Validate one point: a finite, read-only float array of shape ``(n_axes,)``, m."""
    array = np.array(value, dtype=float)
    if array.ndim != 1 or array.size == 0:
        raise ProgramError(f"{name} must be a 1-D array with one entry per axis, got shape {array.shape}")
    if n_axes is not None and array.size != n_axes:
        raise ProgramError(f"{name} must have {n_axes} entries (one per axis), got {array.size}")
    if not np.all(np.isfinite(array)):
        raise ProgramError(f"{name} must be finite, got {array.tolist()}")
    array.setflags(write=False)
    return array


def as_points(points: ArrayLike, n_axes: int) -> FloatArray:
    """Validate a batch of points: float array of shape ``(N, n_axes)``, m."""
    array = np.asarray(points, dtype=float)
    if array.ndim == 1 and array.size == n_axes:
        array = array.reshape(1, n_axes)
    if array.ndim != 2 or array.shape[1] != n_axes:
        raise ProgramError(f"points must have shape (N, {n_axes}), got {array.shape}")
    return array


def require_extent_mm(name: str, value: float, context: str = "", positive: bool = False) -> float:
    """``value`` (mm) if it is a coordinate within +-:data:`MAX_EXTENT_MM`, or with ``positive`` a size (> 0) in
    [:data:`MIN_EXTENT_MM`, :data:`MAX_EXTENT_MM`]; a ConfigError naming ``name``, the bound and the value
    otherwise."""
    number = require_positive(name, value, context) if positive else require_finite(name, value, context)
    low = MIN_EXTENT_MM if positive else -MAX_EXTENT_MM
    if not low <= number <= MAX_EXTENT_MM:
        where = f"{context}.{name}" if context else name
        raise ConfigError(f"{where} must be in [{low:g}, {MAX_EXTENT_MM:g}] mm, got {value!r}")
    return number


def require_feed_mm_min(name: str, value: float, context: str = "") -> float:
    """A programmed feed (mm/min) if it is finite and >= :data:`MIN_FEED_MM_MIN`; a ConfigError naming ``name``,
    the bound and the value otherwise."""
    number = require_positive(name, value, context)
    if number < MIN_FEED_MM_MIN:
        where = f"{context}.{name}" if context else name
        raise ConfigError(f"{where} must be >= {MIN_FEED_MM_MIN:g} mm/min, got {value!r}")
    return number


def require_feed(feed_m_s: float) -> float:
    try:
        return require_positive("feed_m_s", feed_m_s)
    except ConfigError as err:
        raise ProgramError(str(err)) from err


def max_abs_cos(low_rad: float, high_rad: float) -> float:
    """Largest ``|cos θ|`` for θ in ``[low_rad, high_rad]``."""
    k = math.ceil(low_rad / math.pi)
    if k * math.pi <= high_rad:
        return 1.0
    return max(abs(math.cos(low_rad)), abs(math.cos(high_rad)))
