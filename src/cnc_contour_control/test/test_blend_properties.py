"""Generated programs under corner blending: limits, tolerance and time on every sample (hypothesis).

Random polylines, zig-zags, line-and-arc chains in the xy plane and 3-axis paths, random limits (the
split or the combined arc budget, 50 % or 80 % of it centripetal) and two random tolerances P < P2:

- every sample's axis velocity and acceleration, analytic and by finite differences of the sampled
  positions, within the limits (ratio <= 1 + 1e-9; ``test_interpolation.check_limits``);
- every sample within P of the programmed path (exact distance to the programmed segments);
- the cycle time at P and at P2 no longer than exact stop's (G61).

A larger tolerance is not always quicker: a larger blend arc in a stretch where the path speeds up gives
more of the path the arc's lower tangential acceleration (0.21233 s at P2 = 0.5 mm against 0.21163 s at
P = 0.002 mm on a 0.2 mm + 3.9 mm corner of 7°, split budget), so that is not asserted.

``CNC_BLEND_PROGRAMS`` sets the examples per kind (the test command runs a few; 400 is the measurement).
"""
from __future__ import annotations

import math
import os
from collections.abc import Callable

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment, Program, Segment
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.testing import sibling_module

# its check_limits, the one limit check of the planner
_INTERPOLATION_TESTS = sibling_module(__file__, "test_interpolation")

EXAMPLES = int(os.environ.get("CNC_BLEND_PROGRAMS", "12"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
FEED_M_S = 1300 / 60000
SAMPLE_S = 1e-3
#: Rounding allowed on the cycle-time comparisons (relative).
TIME_RTOL = 1e-12

lengths_m = st.floats(2e-4, 6e-3)
turns_rad = st.floats(-math.pi + 0.01, math.pi - 0.01)
programmed_feed = st.just(FEED_M_S)


def _line_program(points_m: list[np.ndarray]) -> Program:
    axes = ("x", "y", "z")[:len(points_m[0])]
    return Program("generated", axes, tuple(LineSegment(points_m[i], points_m[i + 1], FEED_M_S)
                                            for i in range(len(points_m) - 1)))


@st.composite
def polylines(draw: st.DrawFn) -> Program:
    """2-10 lines in xy, random lengths and turns."""
    points, heading = [np.zeros(2)], 0.0
    for length, turn in draw(st.lists(st.tuples(lengths_m, turns_rad), min_size=2, max_size=10)):
        heading += turn
        points.append(points[-1] + length * np.array([math.cos(heading), math.sin(heading)]))
    return _line_program(points)


@st.composite
def zigzags(draw: st.DrawFn) -> Program:
    """3-12 equal lines alternately up and down, turning by 60-178° (the sharp corners where a stop can win)."""
    turn, length = draw(st.floats(math.radians(60), math.radians(178))), draw(lengths_m)
    count = draw(st.integers(3, 12))
    half = 0.5 * (math.pi - turn)
    points = [np.zeros(2)]
    for i in range(count):
        points.append(points[-1] + length * np.array([math.sin(half), math.cos(half) * (1 if i % 2 == 0 else -1)]))
    return _line_program(points)


@st.composite
def arc_chains(draw: st.DrawFn, min_size: int = 2, max_size: int = 8,
               feeds_m_s: st.SearchStrategy[float] = programmed_feed) -> Program:
    """Lines and arcs (radius 0.3-5 mm, sweep up to 170°, either direction) in xy, joined at random corners
    (``min_size``-``max_size`` segments, each with a feed drawn from ``feeds_m_s``)."""
    position, heading, segments = np.zeros(2), 0.0, list[Segment]()
    for is_arc, turn in draw(st.lists(st.tuples(st.booleans(), turns_rad), min_size=min_size, max_size=max_size)):
        heading += turn
        feed = draw(feeds_m_s)
        if not is_arc:
            end = position + draw(lengths_m) * np.array([math.cos(heading), math.sin(heading)])
            segments.append(LineSegment(position, end, feed))
        else:
            radius, sweep = draw(st.floats(3e-4, 5e-3)), draw(st.floats(0.1, math.radians(170)))
            side = draw(st.sampled_from([1.0, -1.0]))
            center = position + side * radius * np.array([-math.sin(heading), math.cos(heading)])
            angle = math.atan2(*(position - center)[::-1]) + side * sweep
            end = center + radius * np.array([math.cos(angle), math.sin(angle)])
            segments.append(ArcSegment(position, end, center, side < 0.0, (0, 1), feed))
            heading += side * sweep
        position = segments[-1].end_m
    return Program("generated", ("x", "y"), tuple(segments))


@st.composite
def paths_3axis(draw: st.DrawFn) -> Program:
    """2-8 lines in xyz: each moves a random pair of axes or all three (corners in and out of a plane)."""
    points = [np.zeros(3)]
    for axes, length, angle in draw(st.lists(st.tuples(st.sampled_from([(0, 1), (0, 2), (1, 2), (0, 1, 2)]),
                                                       lengths_m, turns_rad), min_size=2, max_size=8)):
        step = np.zeros(3)
        step[list(axes[:2])] = [math.cos(angle), math.sin(angle)]
        if len(axes) == 3:
            step[2] = 0.5
        points.append(points[-1] + length * step / np.linalg.norm(step))
    return _line_program(points)


@st.composite
def planner_options(draw: st.DrawFn, n_axes: int) -> tuple[AxisLimits, float, float, float, bool]:
    """Limits (10-60 mm/s, 0.1-2 m/s² per axis), P < P2 (mm), the centripetal share and the budget."""
    velocity = tuple(draw(st.floats(0.01, 0.06)) for _ in range(n_axes))
    acceleration = tuple(draw(st.floats(0.1, 2.0)) for _ in range(n_axes))
    low, high = sorted((draw(st.floats(1e-3, 0.5)), draw(st.floats(1e-3, 0.5))))
    return (AxisLimits(velocity, acceleration), low, high, draw(st.sampled_from([0.5, 0.8])),
            draw(st.booleans()))


def check_program(program: Program, options: tuple[AxisLimits, float, float, float, bool]) -> None:
    """Limits and tolerance at every sample at P, and time(P), time(P2) <= time(G61)."""
    limits, low_mm, high_mm, fraction, combined = options

    def plan(tolerance_mm: float) -> Interpolator:
        return Interpolator(program, limits, InterpolatorConfig(
            path_tolerance_mm=tolerance_mm, arc_centripetal_fraction=fraction, arc_combined_budget=combined,
            clamp_feed=True))

    exact, low, high = plan(0.0), plan(low_mm), plan(high_mm)
    _INTERPOLATION_TESTS.check_limits(low, dt_s=SAMPLE_S, rtol=1e-9)
    positions = low.sample_array(np.arange(0.0, low.duration_s + SAMPLE_S, SAMPLE_S)).position_m
    assert float(np.max(low.blended.deviation_m(positions))) <= low_mm * 1e-3 * (1 + 1e-9)
    assert low.duration_s <= exact.duration_s * (1 + TIME_RTOL)
    assert high.duration_s <= exact.duration_s * (1 + TIME_RTOL)


def _property(programs: st.SearchStrategy[Program], n_axes: int) -> Callable[[], None]:
    @SETTINGS
    @given(programs, planner_options(n_axes))
    def run(program: Program, options: tuple[AxisLimits, float, float, float, bool]) -> None:
        check_program(program, options)
    return run


test_polylines = _property(polylines(), 2)
test_zigzags = _property(zigzags(), 2)
test_arc_chains = _property(arc_chains(), 2)
test_3axis_paths = _property(paths_3axis(), 3)
