"""The interpolator's reference: one sample (:class:`ReferenceSample`), many (:class:`ReferenceTrajectory`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ReferenceSample:
    """The reference at one instant; arrays have shape ``(n_axes,)``.

    ``feed_m_s`` is the instantaneous path speed, ``programmed_feed_m_s`` the
    current segment's programmed feed, ``profile_time_s`` the profile time τ
    and ``feed_override_ratio`` the override applied (1.0 for :meth:`Interpolator.sample`).
    """

    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray
    path_length_m: float
    segment_index: int
    feed_m_s: float
    programmed_feed_m_s: float
    done: bool
    profile_time_s: float = 0.0
    feed_override_ratio: float = 1.0


@dataclass(frozen=True)
class ReferenceTrajectory:
    """Many samples at once: ``(M,)`` per-sample values and ``(M, n_axes)`` axis arrays."""

    time_s: FloatArray
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray
    path_length_m: FloatArray
    segment_index: NDArray[np.intp]
    feed_m_s: FloatArray
    done: NDArray[np.bool_]
