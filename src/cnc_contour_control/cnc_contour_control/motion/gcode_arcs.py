"""Arc centres of G2/G3 blocks: from I/J/K offsets (G91.1 incremental, G90.1 absolute) or a radius R.

Positions are in mm, one entry per program axis. A plane's two axes are
given in the order that defines the arc direction (G17 X then Y, G18 Z then
X, G19 Y then Z): counter-clockwise is from the first toward the second,
i.e. seen from the positive third axis.

R format: ``|R|`` is the radius; R > 0 takes the arc of at most 180°, R < 0
the longer one. The centre lies on the chord's perpendicular bisector, on
the left of the chord (start to end) for a short counter-clockwise (G3) or a
long clockwise (G2) arc, on the right otherwise. An R smaller than half the
chord by more than :data:`R_TOLERANCE_MM` is refused; within it the arc is a
half circle.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from cnc_contour_control.motion.gcode_words import Block
from cnc_contour_control.motion.geometry import FloatArray

#: Plane code -> the axis letters spanning it, in the order that defines the arc direction.
PLANES: dict[str, tuple[str, str]] = {"17": ("X", "Y"), "18": ("Z", "X"), "19": ("Y", "Z")}
#: Centre-offset letter -> the axis letter it offsets.
OFFSETS: dict[str, str] = {"I": "X", "J": "Y", "K": "Z"}
#: How far |R| may fall short of half the chord (rounding in CAM output), mm.
R_TOLERANCE_MM = 1.0e-3


@dataclass(frozen=True)
class ArcFrame:
    """What an arc's centre depends on: positions in mm (program axes), the plane's axis indices.

    ``work_offset_mm`` is added to absolute (G90.1) centre words; ``scale``
    turns program units into mm (25.4 under G20).
    """

    start_mm: FloatArray
    end_mm: FloatArray
    plane: tuple[int, int]
    plane_code: str
    clockwise: bool
    scale: float
    work_offset_mm: FloatArray


def center_from_offsets(block: Block, frame: ArcFrame, offsets: Mapping[str, tuple[float, str]],
                        axis_index: Mapping[str, int], absolute: bool) -> FloatArray:
    """The centre (mm) from I/J/K: added to the start (G91.1) or absolute in the work offset (G90.1)."""
    letters = PLANES[frame.plane_code]
    allowed = {k for k, v in OFFSETS.items() if v in letters}
    for letter, (_, raw) in offsets.items():
        if letter not in allowed:
            raise block.error(f"{raw} is not allowed in plane G{frame.plane_code} (use {'/'.join(sorted(allowed))})")
    if absolute and set(offsets) != allowed:
        raise block.error(f"G90.1 (absolute arc centre) needs both {'/'.join(sorted(allowed))}, "
                          f"got {sorted(offsets) or 'none'}")
    center = frame.start_mm.copy()
    for letter, (value, _) in offsets.items():
        index = axis_index[OFFSETS[letter]]
        base = frame.work_offset_mm[index] if absolute else frame.start_mm[index]
        center[index] = base + value * frame.scale
    return center


def center_from_radius(block: Block, frame: ArcFrame, radius_word: tuple[float, str]) -> FloatArray:
    """The centre (mm) of the R-format arc from ``frame.start_mm`` to ``frame.end_mm`` (module notes)."""
    value, raw = radius_word
    radius_mm = abs(value) * frame.scale
    a, b = frame.plane
    chord = np.array([frame.end_mm[a] - frame.start_mm[a], frame.end_mm[b] - frame.start_mm[b]])
    chord_mm = float(np.hypot(chord[0], chord[1]))
    if chord_mm < 1.0e-6 or radius_mm <= 0.0:
        raise block.error(f"{raw}: an R arc needs R != 0 and an end other than its start in plane "
                          f"G{frame.plane_code} (a full circle needs I/J/K)")
    half_mm = 0.5 * chord_mm
    if radius_mm < half_mm - R_TOLERANCE_MM:
        raise block.error(f"{raw}: radius {radius_mm:.6g} mm is smaller than half the chord, "
                          f"{half_mm:.6g} mm (no circle of that radius joins the start and the end)")
    rise_mm = math.sqrt(max(radius_mm * radius_mm - half_mm * half_mm, 0.0))
    left = np.array([-chord[1], chord[0]]) / chord_mm
    side = (-1.0 if frame.clockwise else 1.0) * (1.0 if value > 0.0 else -1.0)
    center = frame.start_mm.copy()
    center[a] = frame.start_mm[a] + 0.5 * chord[0] + side * rise_mm * left[0]
    center[b] = frame.start_mm[b] + 0.5 * chord[1] + side * rise_mm * left[1]
    return center
