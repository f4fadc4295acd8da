"""Corner blending within a path tolerance (G64 P): geometry, tolerance at every sample, limits, time."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.blending import blend_program, corner_trim_m
from cnc_contour_control.config import build_config
from cnc_contour_control.errors import ConfigError
from cnc_contour_control.gcode import parse_gcode
from cnc_contour_control.geometry import ArcSegment, Dwell, LineSegment, Program
from cnc_contour_control.interpolation import AxisLimits, Interpolator, InterpolatorConfig
from cnc_tools.sibling_tests import sibling_module


_INTERPOLATION_TESTS = sibling_module(__file__, "test_interpolation")  # its check_limits, the one limit check of the planner

LIMITS_2 = AxisLimits((2000 / 60000,) * 2, (0.25, 0.25))
LIMITS_3 = AxisLimits((2000 / 60000,) * 3, (0.25, 0.25, 0.4))
FEED_M_S = 1300 / 60000


def polyline(points_m: np.ndarray, feed_m_s: float = FEED_M_S, axes: tuple[str, ...] = ("x", "y")) -> Program:
    return Program("polyline", axes, tuple(LineSegment(points_m[i], points_m[i + 1], feed_m_s)
                                           for i in range(len(points_m) - 1)))


def polygon(sides: int, radius_m: float = 0.02) -> Program:
    angles = np.linspace(0.0, 2.0 * math.pi, sides + 1)
    points = np.c_[radius_m * np.cos(angles), radius_m * np.sin(angles)]
    points[-1] = points[0]
    return polyline(points)


def star(points: int = 5, outer_m: float = 0.02, inner_m: float = 0.006) -> Program:
    angles = np.linspace(0.0, 2.0 * math.pi, 2 * points + 1)
    radii = np.where(np.arange(2 * points + 1) % 2 == 0, outer_m, inner_m)
    vertices = np.c_[radii * np.cos(angles), radii * np.sin(angles)]
    vertices[-1] = vertices[0]
    return polyline(vertices)


def check_limits(interpolator: Interpolator, dt_s: float = 2e-4) -> None:
    """test_interpolation's analytic and finite-difference limit check, to 1e-9."""
    _INTERPOLATION_TESTS.check_limits(interpolator, dt_s=dt_s, rtol=1e-9)


def worst_deviation_m(interpolator: Interpolator, dt_s: float = 5e-4) -> float:
    """Largest exact distance of the planned reference from the programmed path, m."""
    trajectory = interpolator.sample_array(np.arange(0.0, interpolator.duration_s + dt_s, dt_s))
    return float(np.max(interpolator.blended.deviation_m(trajectory.position_m)))


def blended(program: Program, tolerance_mm: float, limits: AxisLimits = LIMITS_2) -> Interpolator:
    return Interpolator(program, limits, InterpolatorConfig(path_tolerance_mm=tolerance_mm))


def test_right_angle_blend_matches_the_hand_calculation() -> None:
    """90°: e = R (√2 - 1) = tolerance, so R = 0.01 mm / 0.41421 = 24.14 µm and d = R tan 45° = R."""
    radius, trim = corner_trim_m(math.pi / 2, 1e-5, 1.0)
    assert radius == pytest.approx(1e-5 / (math.sqrt(2.0) - 1.0))
    assert trim == pytest.approx(radius)
    assert corner_trim_m(math.pi / 2, 1e-5, 1e-6) == pytest.approx((1e-6, 1e-6))


def test_a_corner_becomes_line_arc_line_tangent_at_both_ends() -> None:
    program = polyline(np.array([[0.0, 0.0], [0.01, 0.0], [0.01, 0.01]]))
    plan = blend_program(program, 1e-5)
    kinds = [type(s).__name__ for s in plan.planned.segments]
    assert kinds == ["LineSegment", "ArcSegment", "LineSegment"]
    arc = plan.planned.segments[1]
    assert isinstance(arc, ArcSegment) and not arc.clockwise
    assert_allclose(arc.tangent(0.0), [1.0, 0.0], atol=1e-12)
    assert_allclose(arc.tangent(arc.length_m), [0.0, 1.0], atol=1e-12)
    assert plan.blends[0].deviation_m == pytest.approx(1e-5)


@pytest.mark.parametrize("program", [polygon(36), polygon(360), star()], ids=["36-gon", "360-gon", "star"])
@pytest.mark.parametrize("tolerance_mm", [0.001, 0.01, 0.1])
def test_tolerance_and_limits_hold_at_every_sample(program: Program, tolerance_mm: float) -> None:
    interpolator = blended(program, tolerance_mm)
    assert worst_deviation_m(interpolator) <= tolerance_mm * 1e-3 * (1 + 1e-9)
    check_limits(interpolator, dt_s=5e-4)


def test_three_axis_corners_in_a_coordinate_plane_blend_others_stop() -> None:
    points = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.002], [0.02, 0.0, 0.0], [0.02, 0.005, 0.001]])
    interpolator = blended(polyline(points, axes=("x", "y", "z")), 0.01, LIMITS_3)
    assert [b.junction for b in interpolator.blended.blends] == [1]
    assert interpolator.junction_speeds_m_s[2] > 0.0
    assert interpolator.junction_speeds_m_s[-2] == 0.0
    assert worst_deviation_m(interpolator) <= 1e-5 * (1 + 1e-9)
    check_limits(interpolator)


def test_36_gon_at_1300_mm_min_runs_far_faster_than_stopping_at_every_corner() -> None:
    stop = Interpolator(polygon(36), LIMITS_2).duration_s
    fast = blended(polygon(36), 0.01).duration_s
    assert fast < 0.75 * stop
    assert np.count_nonzero(blended(polygon(36), 0.01).junction_speeds_m_s == 0.0) == 2


def test_360_gon_within_10_percent_of_the_true_arc() -> None:
    circle = Program("circle", ("x", "y"), (ArcSegment([0.02, 0.0], [0.02, 0.0], [0.0, 0.0], False, (0, 1),
                                                       FEED_M_S),))
    arc_s = Interpolator(circle, LIMITS_2).duration_s
    assert blended(polygon(360), 0.01).duration_s <= 1.1 * arc_s


def test_short_moves_do_not_force_stops() -> None:
    """A 2000-move zig-zag of 0.2 mm steps: speed only reaches 0 at the ends."""
    x = np.arange(2001) * 2e-4
    points = np.c_[x, np.where(np.arange(2001) % 2 == 0, 0.0, 5e-5)]
    interpolator = blended(polyline(points), 0.01)
    assert np.all(interpolator.junction_speeds_m_s[1:-1] > 0.0)
    check_limits(interpolator, dt_s=1e-3)


def test_tolerance_zero_is_todays_plan_bit_for_bit() -> None:
    program = star()
    today, zero = Interpolator(program, LIMITS_2), blended(program, 0.0)
    assert zero.program is program and zero.programmed_program is program
    times = np.linspace(0.0, today.duration_s, 997)
    assert zero.duration_s == today.duration_s
    assert np.array_equal(zero.sample_array(times).position_m, today.sample_array(times).position_m)


def test_g61_is_exact_stop_and_g64_p_overrides_the_configuration() -> None:
    square = "G1 X10 F1300\nY10\nX0\nY0\n"
    exact = Interpolator(parse_gcode("G61\n" + square, ("x", "y")), LIMITS_2,
                         InterpolatorConfig(path_tolerance_mm=0.1))
    assert exact.blended.blends == () and np.all(exact.junction_speeds_m_s == 0.0)
    g64 = Interpolator(parse_gcode("G64 P0.02\n" + square, ("x", "y")), LIMITS_2)
    assert [b.junction for b in g64.blended.blends] == [1, 2, 3]
    assert max(b.deviation_m for b in g64.blended.blends) == pytest.approx(2e-5)
    assert worst_deviation_m(g64) <= 2e-5 * (1 + 1e-9)


def test_arcs_and_dwells_keep_their_exact_stop() -> None:
    line = LineSegment([0.0, 0.0], [0.01, 0.0], FEED_M_S)
    arc = ArcSegment([0.01, 0.0], [0.02, 0.0], [0.015, -0.002], True, (0, 1), FEED_M_S)
    after = LineSegment([0.02, 0.0], [0.02, 0.01], FEED_M_S)
    last = LineSegment([0.02, 0.01], [0.0, 0.01], FEED_M_S)
    program = Program("mixed", ("x", "y"), (line, arc, after, last), dwells=(Dwell(3, 0.5),))
    plan = blend_program(program, 1e-4)
    assert plan.blends == () and plan.planned is program


@pytest.mark.parametrize("value", [-0.01, math.nan, math.inf])
def test_bad_tolerance_is_refused_naming_the_option(value: float) -> None:
    with pytest.raises(ConfigError, match="path_tolerance_mm"):
        InterpolatorConfig(path_tolerance_mm=value)


def test_local_deviation_bounds_the_exact_contour_distance() -> None:
    interpolator = blended(star(), 0.05)
    trajectory = interpolator.sample_array(np.linspace(0.0, interpolator.duration_s, 4001))
    exact = interpolator.blended.deviation_m(trajectory.position_m)
    local = interpolator.blended.local_deviation_m(trajectory.position_m, trajectory.segment_index)
    assert np.all(local >= exact - 1e-15)
    assert np.max(local) <= 5e-5 * (1 + 1e-9)
    assert np.max(local) == pytest.approx(np.max(exact), rel=0.05)


def test_the_scenario_key_is_path_tolerance_mm() -> None:
    config = build_config(InterpolatorConfig, {"path_tolerance_mm": 0.01}, "scenario.interpolator")
    assert blended(polygon(36), config.path_tolerance_mm).duration_s == Interpolator(
        polygon(36), LIMITS_2, config).duration_s
    with pytest.raises(ConfigError, match="path_tolerance_mm must be in"):
        build_config(InterpolatorConfig, {"path_tolerance_mm": -1.0}, "scenario.interpolator")
