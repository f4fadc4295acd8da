"""Unit conversions: the one place where people's units meet SI.

Topics and core APIs are SI (m, m/s, s). Configs and reports may use mm,
µm, m/min or BLU; every such name carries its unit.
"""
from __future__ import annotations

from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

#: One value or an array of them (a conversion works elementwise and keeps the kind).
_Value = TypeVar("_Value", float, NDArray[np.float64])

M_PER_MM = 1.0e-3
M_PER_UM = 1.0e-6
#: Paper 000's basic length unit, 10 µm.
M_PER_BLU_PAPER000 = 1.0e-5
#: Paper 002's encoder pulse, 1/2.4 µm.
M_PER_PULSE_PAPER002 = 1.0e-6 / 2.4
#: mm/min per m/s (the feed of the cutting processes, paper 004).
MM_MIN_PER_M_S = 60000.0


def mm_to_m(value_mm: _Value) -> _Value:
    """Millimetres to metres."""
    return value_mm * M_PER_MM


def m_to_mm(value_m: float) -> float:
    """Metres to millimetres."""
    return value_m / M_PER_MM


def mm_min_to_m_s(feed_mm_min: float) -> float:
    """A feedrate in mm/min to m/s."""
    return feed_mm_min * M_PER_MM / 60.0


def m_s_to_mm_min(speed_m_s: float) -> float:
    """A speed in m/s to mm/min."""
    return speed_m_s / M_PER_MM * 60.0


def mm_s2_to_m_s2(accel_mm_s2: float) -> float:
    """An acceleration in mm/s^2 to m/s^2."""
    return accel_mm_s2 * M_PER_MM
