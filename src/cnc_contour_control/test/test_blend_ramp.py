"""3-axis line-arc corners (a line leaving a planar arc's plane) under blending: the three-arc blend.

Geometry (pieces contiguous and tangent-continuous from the line to the arc, either order), a designed
case where the blend is used and quicker (a 30° ramp into a G17 arc), and generated programs (hypothesis):
random arc plane, radius, sweep and direction, the line's elevation and heading, either order, a helix
instead of the arc (not blended: stays a stop), limits, P and feed; with and without a jerk limit (fir):

- every sample's axis velocity, acceleration (and jerk) within the limits (ratio <= 1 + 1e-9,
  :func:`~cnc_contour_control.motion.reference_check.limit_ratios`);
- every sample within P of the programmed path (exact distance to the programmed segments);
- without a jerk limit, the cycle time no longer than exact stop's (G61).
"""
from __future__ import annotations

import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.blend_ramp import plan_ramp
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment, Program, Segment
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.reference_check import limit_ratios, sample_reference

EXAMPLES = int(os.environ.get("CNC_BLEND_PROGRAMS", "8"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
FEED_M_S = 1300 / 60000
SAMPLE_S = 1e-3
LIMITS = AxisLimits((2000 / 60000,) * 3, (0.25, 0.25, 0.4))


def ramp_program(elevation_rad: float, heading_rad: float, radius_m: float = 0.01, sweep_rad: float = math.pi / 2,
                 plane: tuple[int, int] = (0, 1), clockwise: bool = False, line_first: bool = True,
                 rise_m: float = 0.0, feed_m_s: float = FEED_M_S, line_m: float = 0.01) -> Program:
    """A line at ``elevation_rad`` off ``plane``, heading ``heading_rad`` from the arc's start tangent in it,
    then the arc (or the arc, then the line back out); ``rise_m`` makes the arc a helix."""
    a, b = plane
    z = 3 - a - b
    side = -1.0 if clockwise else 1.0
    center = np.zeros(3)
    center[b] = side * radius_m
    end = center.copy()
    angle = -side * math.pi / 2 + side * sweep_rad
    end[a], end[b], end[z] = center[a] + radius_m * math.cos(angle), center[b] + radius_m * math.sin(angle), rise_m
    arc = ArcSegment(np.zeros(3), end, center, clockwise, plane, feed_m_s)
    u = np.zeros(3)
    u[a] = math.cos(elevation_rad) * math.cos(heading_rad)
    u[b] = math.cos(elevation_rad) * math.sin(heading_rad)
    u[z] = -math.sin(elevation_rad)
    segments: tuple[Segment, ...]
    if line_first:
        segments = (LineSegment(-line_m * u, np.zeros(3), feed_m_s), arc)
    else:
        back = ArcSegment(end, np.zeros(3), center, not clockwise, plane, feed_m_s)
        segments = (back, LineSegment(np.zeros(3), -line_m * u, feed_m_s))
    return Program("ramp", ("x", "y", "z"), segments)


@pytest.mark.parametrize("line_first", [True, False])
@pytest.mark.parametrize("elevation_deg, heading_deg", [(30, 0), (20, -40), (45, 60), (80, 0)])
def test_pieces_join_the_line_and_the_arc_tangentially(line_first: bool, elevation_deg: float,
                                                       heading_deg: float) -> None:
    program = ramp_program(math.radians(elevation_deg), math.radians(heading_deg), line_first=line_first)
    before, after = program.segments
    blend = plan_ramp(before, after, 1e-4)
    assert blend is not None and len(blend.pieces) in (2, 3) and 0.0 < blend.deviation_m <= 1e-4
    ends = [before.point(before.length_m - blend.trim_before_m)] + [p.end_m for p in blend.pieces]
    starts = [p.start_m for p in blend.pieces] + [after.point(blend.trim_after_m)]
    assert max(math.dist(p, q) for p, q in zip(ends, starts)) < 1e-12
    heads = [before.tangent(before.length_m - blend.trim_before_m)] + [p.tangent(p.length_m) for p in blend.pieces]
    tails = [p.tangent(0.0) for p in blend.pieces] + [after.tangent(blend.trim_after_m)]
    assert max(float(np.linalg.norm(p - q)) for p, q in zip(heads, tails)) < 1e-9


@pytest.mark.parametrize("tolerance_mm", [0.01, 0.1])
def test_a_30_degree_ramp_into_an_xy_arc_is_blended_and_quicker(tolerance_mm: float) -> None:
    """The ramp heads along the arc's start tangent: the S (no single circle joins there)."""
    program = ramp_program(math.radians(30), 0.0)
    stop, _ = sample_reference(program, LIMITS, InterpolatorConfig())
    blended, reference = sample_reference(program, LIMITS, InterpolatorConfig(path_tolerance_mm=tolerance_mm))
    assert [len(b.pieces) for b in blended.blended.blends] == [3]
    assert blended.junction_speeds_m_s[1] > 0.0
    assert blended.duration_s < stop.duration_s - 0.03
    assert float(np.max(blended.blended.deviation_m(reference.position_m))) <= tolerance_mm * 1e-3
    assert limit_ratios(reference.position_m, SAMPLE_S, LIMITS).worst() <= 1.0 + 1e-9


@st.composite
def ramp_cases(draw: st.DrawFn) -> tuple[Program, AxisLimits, float]:
    """A generated ramp-arc program, its limits (optionally a jerk limit) and P (mm)."""
    helix = draw(st.booleans()) and draw(st.booleans())
    program = ramp_program(
        draw(st.floats(math.radians(3), math.radians(87))), draw(st.floats(-math.pi * 0.9, math.pi * 0.9)),
        draw(st.floats(1e-3, 2e-2)), draw(st.floats(0.3, math.radians(170))),
        draw(st.sampled_from([(0, 1), (2, 0), (1, 2)])), draw(st.booleans()), draw(st.booleans()),
        draw(st.floats(1e-3, 5e-3)) if helix else 0.0, draw(st.floats(0.005, 0.05)), draw(st.floats(1e-3, 2e-2)))
    velocity = tuple(draw(st.floats(0.01, 0.06)) for _ in range(3))
    acceleration = tuple(draw(st.floats(0.1, 2.0)) for _ in range(3))
    jerk = tuple(draw(st.floats(2.0, 50.0)) for _ in range(3)) if draw(st.booleans()) else None
    return program, AxisLimits(velocity, acceleration, jerk), draw(st.floats(5e-3, 0.5))


@SETTINGS
@given(ramp_cases())
def test_generated_ramps_keep_limits_tolerance_and_time(case: tuple[Program, AxisLimits, float]) -> None:
    program, limits, tolerance_mm = case
    planner, reference = sample_reference(program, limits, InterpolatorConfig(path_tolerance_mm=tolerance_mm,
                                                                              clamp_feed=True), SAMPLE_S)
    assert limit_ratios(reference.position_m, SAMPLE_S, limits).worst() <= 1.0 + 1e-9
    assert float(np.max(planner.blended.deviation_m(reference.position_m))) <= tolerance_mm * 1e-3 * (1 + 1e-9)
    if limits.max_jerk_m_s3 is None:
        stop, _ = sample_reference(program, limits, InterpolatorConfig(clamp_feed=True), SAMPLE_S)
        assert planner.duration_s <= stop.duration_s * (1 + 1e-12)
