"""Tier 1: the segment prefilter of Program.contour_distance gives the scan's distances and indices exactly."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_contour_control.motion import geometry
from cnc_contour_control.motion.gcode import parse_gcode


def zigzag_with_arcs(n: int) -> geometry.Program:
    """``n`` blocks: short lines and quarter arcs crossing back over each other (ties and near ties)."""
    lines, x, y = ["G1 F600"], 0.0, 0.0
    for i in range(n):
        if i % 5:
            x, y = (i % 40) * 0.5, (i // 40) * 0.5 + (i % 3) * 0.25
            lines.append(f"G1 X{x:.3f} Y{y:.3f}")
        else:
            x += 1.0
            lines.append(f"G3 X{x:.3f} Y{y:.3f} R1")
    return parse_gcode("\n".join(lines), ("x", "y"))


def test_the_prefilter_gives_the_scans_distances_and_indices(monkeypatch: pytest.MonkeyPatch) -> None:
    program = zigzag_with_arcs(600)
    assert len(program.segments) >= geometry.PREFILTER_MIN_SEGMENTS
    rng = np.random.default_rng(7)
    points = np.vstack([rng.uniform(-0.005, 0.025, (300, 2)), program.segment_boxes().vertex_m[::7],
                        [[math.nan, 0.0], [1.0, 1.0]]])
    filtered = program.contour_distance(points)
    monkeypatch.setattr(geometry, "PREFILTER_MIN_SEGMENTS", math.inf)
    scanned = program.contour_distance(points)
    assert np.array_equal(filtered[0], scanned[0], equal_nan=True)
    assert np.array_equal(filtered[1], scanned[1])
    assert len(program.segment_boxes().candidates(points[:1])) < len(program.segments) / 4, "most are left out"
