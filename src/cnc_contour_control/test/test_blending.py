"""Corner blending within a path tolerance (G64 P): geometry, tolerance at every sample, limits, time."""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError, ProgramError
from cnc_contour_control.motion.arc_budget import combined_tangential_m_s2
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.blending import blend_program, corner_trim_m
from cnc_contour_control.motion.gcode import parse_gcode
from cnc_contour_control.motion.geometry import ArcSegment, Dwell, LineSegment, Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.segment_tangents import end_tangents
from cnc_contour_control.testing import sibling_module

# its check_limits, the one limit check of the planner
_INTERPOLATION_TESTS = sibling_module(__file__, "test_interpolation")

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
    """90°: e = R (1 - cos 45°) = tolerance (to the lines), so R = 0.01 mm / 0.29289 = 34.14 µm, d = R tan 45° = R."""
    radius, trim = corner_trim_m(math.pi / 2, 1e-5, 1.0)
    assert radius == pytest.approx(1e-5 / (1.0 - math.sqrt(0.5)))
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
    # 80 % of the acceleration for the arcs: there a 90° blend within 20 µm is quicker than a stop (at 50 % not)
    g64 = Interpolator(parse_gcode("G64 P0.02\n" + square, ("x", "y")), LIMITS_2,
                       InterpolatorConfig(arc_centripetal_fraction=0.8))
    assert [b.junction for b in g64.blended.blends] == [1, 2, 3]
    assert max(b.deviation_m for b in g64.blended.blends) == pytest.approx(2e-5)
    assert worst_deviation_m(g64) <= 2e-5 * (1 + 1e-9)


def test_dwells_and_helices_keep_their_exact_stop() -> None:
    line = LineSegment([0.0, 0.0, 0.0], [0.01, 0.0, 0.0], FEED_M_S)
    helix = ArcSegment([0.01, 0.0, 0.0], [0.02, 0.0, 0.001], [0.015, -0.002, 0.0], True, (0, 1), FEED_M_S)
    after = LineSegment([0.02, 0.0, 0.001], [0.02, 0.01, 0.001], FEED_M_S)
    last = LineSegment([0.02, 0.01, 0.001], [0.0, 0.01, 0.001], FEED_M_S)
    program = Program("mixed", ("x", "y", "z"), (line, helix, after, last), dwells=(Dwell(3, 0.5),))
    plan = blend_program(program, 1e-4)
    assert plan.blends == () and plan.planned is program


def scallops(sweep_rad: float = math.pi / 2, radii_m: tuple[float, ...] = (5e-4, 1e-3, 2e-3, 4e-3)) -> Program:
    """Clockwise arcs of the given radii along x, each bulging up: an arc-arc corner at every junction."""
    segments, x = [], 0.0
    for radius in radii_m * 2:
        chord = 2 * radius * math.sin(sweep_rad / 2)
        segments.append(ArcSegment([x, 0.0], [x + chord, 0.0], [x + chord / 2, -radius * math.cos(sweep_rad / 2)],
                                   True, (0, 1), FEED_M_S))
        x += chord
    return Program("scallops", ("x", "y"), tuple(segments))


def lines_and_arcs() -> Program:
    """Lines of 3 mm alternating with 120° arcs of R 0.5-4 mm: line-arc and arc-line corners of 60°."""
    segments, x = [], 0.0
    for radius in (5e-4, 1e-3, 2e-3, 4e-3):
        segments.append(LineSegment([x, 0.0], [x + 3e-3, 0.0], FEED_M_S))
        x += 3e-3
        chord = 2 * radius * math.sin(math.pi / 3)
        segments.append(ArcSegment([x, 0.0], [x + chord, 0.0], [x + chord / 2, -radius / 2], True, (0, 1), FEED_M_S))
        x += chord
    return Program("lines-and-arcs", ("x", "y"), tuple(segments))


def test_line_arc_fillet_is_tangent_to_both_and_on_the_arc() -> None:
    arc = ArcSegment([0.01, 0.0], [0.02, 0.0], [0.015, -0.002], True, (0, 1), FEED_M_S)
    program = Program("la", ("x", "y"), (LineSegment([0.0, 0.0], [0.01, 0.0], FEED_M_S), arc))
    plan = blend_program(program, 1e-5)
    line, fillet, rest = plan.planned.segments
    assert isinstance(fillet, ArcSegment) and not fillet.clockwise  # the corner turns left
    assert_allclose(fillet.tangent(0.0), line.tangent(line.length_m), atol=1e-9)
    assert_allclose(fillet.tangent(fillet.length_m), rest.tangent(0.0), atol=1e-9)
    assert rest.radius_m == pytest.approx(arc.radius_m, abs=1e-12)
    assert_allclose(rest.center_m, arc.center_m)
    assert 0.9e-5 <= plan.blends[0].deviation_m <= 1e-5


@pytest.mark.parametrize("make", [scallops, lines_and_arcs])
@pytest.mark.parametrize("tolerance_mm", [0.001, 0.01, 0.1])
def test_arc_corners_hold_tolerance_and_limits(make: Callable[[], Program], tolerance_mm: float) -> None:
    program = make()
    interpolator = blended(program, tolerance_mm)
    corners = len(program.segments) - 1
    assert len(interpolator.blended.blends) == corners
    assert np.count_nonzero(interpolator.junction_speeds_m_s == 0.0) == 2  # only the ends
    assert worst_deviation_m(interpolator) <= tolerance_mm * 1e-3 * (1 + 1e-9)
    assert max(b.deviation_m for b in interpolator.blended.blends) <= tolerance_mm * 1e-3
    assert interpolator.duration_s < Interpolator(program, LIMITS_2).duration_s
    check_limits(interpolator, dt_s=5e-4)


def test_arc_corner_fillet_deviation_is_the_measured_one() -> None:
    """The blend's recorded deviation is the largest distance of its arc from the path (dense samples: within a step).

    The distance peaks in a kink (where the nearer of the two arcs changes), so samples ``step`` apart may
    miss the peak by up to ``step`` (distance changes at most 1 m per m of arc); they never exceed it.
    """
    plan = blend_program(scallops(), 1e-5)
    for blend, arc in zip(plan.blends, (s for s in plan.planned.segments if s.radius_m < 4e-4)):
        points = arc.point(np.linspace(0.0, arc.length_m, 20001))
        exact = np.max(plan.programmed.contour_distance(points)[0])
        assert blend.deviation_m - arc.length_m / 20000 <= exact <= blend.deviation_m + 1e-15


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


def test_combined_arc_budget_is_the_friction_circle_by_hand() -> None:
    """R 1 mm, 250 mm/s^2, v² κ = 0.15 m/s^2: a_t = sqrt(0.25² - 0.15²) = 0.2 m/s^2 (the split gives 0.1)."""
    arc = ArcSegment([0.001, 0.0], [0.001, 0.0], [0.0, 0.0], False, (0, 1), FEED_M_S)
    speed = math.sqrt(0.15 * 0.001)
    assert combined_tangential_m_s2(arc, speed, np.array([0.25, 0.25])) == pytest.approx(0.2)
    helix = ArcSegment([0.001, 0.0, 0.0], [0.001, 0.0, 0.01], [0.0, 0.0, 0.0], False, (0, 1), FEED_M_S)
    rate = helix.radius_m * helix.sweep_rad / helix.length_m
    kappa = helix.radius_m * (helix.sweep_rad / helix.length_m) ** 2
    expected = min(math.sqrt(0.25**2 - (speed**2 * kappa) ** 2) / rate, 0.1 / (0.01 / helix.length_m))
    assert combined_tangential_m_s2(helix, speed, np.array([0.25, 0.25, 0.1])) == pytest.approx(expected)


@pytest.mark.parametrize("make", [scallops, lines_and_arcs, lambda: polygon(36)])
def test_combined_arc_budget_is_faster_within_the_limits(make: Callable[[], Program]) -> None:
    program = make()
    split = Interpolator(program, LIMITS_2, InterpolatorConfig(path_tolerance_mm=0.01, arc_combined_budget=False,
                                                               arc_centripetal_fraction=0.5))
    combined = Interpolator(program, LIMITS_2, InterpolatorConfig(path_tolerance_mm=0.01, arc_combined_budget=True,
                                                                  arc_centripetal_fraction=0.8))
    assert combined.duration_s < split.duration_s
    check_limits(combined, dt_s=5e-4)


def test_arc_budget_flag_must_be_a_bool() -> None:
    with pytest.raises(ConfigError, match="arc_combined_budget must be true or false, got 'yes'"):
        InterpolatorConfig(arc_combined_budget="yes")


def random_chain(rng: np.random.Generator, axes: tuple[str, ...], plane: tuple[int, int], n: int = 8) -> Program:
    """Lines and arcs (R 0.3-5 mm, sweeps up to a full circle) in ``plane``, joined at random corners."""
    segments, point, heading = [], np.zeros(len(axes)), rng.uniform(0.0, 2.0 * math.pi)
    a, b = plane
    for _ in range(n):
        heading += rng.uniform(-2.5, 2.5)
        direction = np.zeros(len(axes))
        direction[[a, b]] = math.cos(heading), math.sin(heading)
        if rng.random() < 0.5:
            segments.append(LineSegment(point, point + rng.uniform(2e-4, 5e-3) * direction, FEED_M_S))
        else:
            radius, clockwise = rng.uniform(3e-4, 5e-3), bool(rng.random() < 0.5)
            center = point.copy()
            center[[a, b]] += (1.0 if clockwise else -1.0) * radius * np.array([direction[b], -direction[a]])
            sweep = rng.uniform(0.2, 2.0 * math.pi)
            angle = math.atan2(point[b] - center[b], point[a] - center[a]) + (-sweep if clockwise else sweep)
            end = point.copy()
            end[[a, b]] = center[[a, b]] + radius * np.array([math.cos(angle), math.sin(angle)])
            segments.append(ArcSegment(point, end, center, clockwise, plane, FEED_M_S))
            tangent = segments[-1].tangent(segments[-1].length_m)
            heading = math.atan2(tangent[b], tangent[a])
        point = segments[-1].point(segments[-1].length_m)
    return Program("random", axes, tuple(segments))


@pytest.mark.parametrize("seed", range(6))
def test_random_line_arc_chains_hold_tolerance_and_limits(seed: int) -> None:
    """Random chains in XY and (3 axes) XZ, random tolerances 0.001-0.1 mm, both arc budgets."""
    rng = np.random.default_rng(seed)
    axes, plane, limits = (("x", "y"), (0, 1), LIMITS_2) if seed % 2 else (("x", "y", "z"), (0, 2), LIMITS_3)
    program, tolerance_mm = random_chain(rng, axes, plane), 10 ** rng.uniform(-3.0, -1.0)
    interpolator = Interpolator(program, limits, InterpolatorConfig(path_tolerance_mm=tolerance_mm,
                                                                    arc_combined_budget=seed < 3))
    assert interpolator.blended.blends
    assert worst_deviation_m(interpolator) <= tolerance_mm * 1e-3 * (1 + 1e-9)
    check_limits(interpolator, dt_s=5e-4)


def test_g64_blends_the_corners_between_g1_and_g2() -> None:
    """A slot end written as G1, G2 with a corner: blended within P, the blend arc named by the G2's line."""
    text = "G64 P0.01\nG1 X10 F1300\nG2 X14 Y0 I2 J-1\nG1 X20\n"
    interpolator = Interpolator(parse_gcode(text, ("x", "y")), LIMITS_2)
    assert [b.junction for b in interpolator.blended.blends] == [1, 2]
    fillets = [s for s in interpolator.program.segments if isinstance(s, ArcSegment) and s.radius_m < 1e-3]
    assert [s.source_line for s in fillets] == [3, 4]
    assert np.count_nonzero(interpolator.junction_speeds_m_s == 0.0) == 2
    assert worst_deviation_m(interpolator) <= 1e-5 * (1 + 1e-9)
    check_limits(interpolator, dt_s=5e-4)


@pytest.mark.parametrize("seed", range(3))
def test_end_tangents_are_the_segments_own(seed: int) -> None:
    """The planner's vectorised junction tangents equal each segment's tangent() (lines, arcs, helices)."""
    rng = np.random.default_rng(seed)
    segments = random_chain(rng, ("x", "y", "z"), (0, 2), n=12).segments + (
        ArcSegment([0.0, 0.0, 0.0], [0.002, 0.0, 0.001], [0.001, 0.0, 0.0], True, (0, 1), FEED_M_S),)
    start, end = end_tangents(segments)
    assert_allclose(start, [s.tangent(0.0) for s in segments], atol=1e-15)
    assert_allclose(end, [s.tangent(s.length_m) for s in segments], atol=1e-14)


def test_a_feed_over_the_limits_is_refused_naming_the_g_code_line_with_blending() -> None:
    text = "G64 P0.01\nG1 X10 F1300\nG2 X14 Y0 I2 J-1 F2500\nG1 X20 F1300\n"
    with pytest.raises(ProgramError, match=r"line 3 \(segment \d+\): feed_mm_min must be <= 2000 .*, got 2500"):
        Interpolator(parse_gcode(text, ("x", "y")), LIMITS_2)


def zigzag_150(segments: int = 30, length_m: float = 0.005) -> Program:
    """The issue's zig-zag: lines of 5 mm along x, alternately up and down, turning by 150°."""
    half = math.radians(15.0)
    steps = np.array([[math.cos(half), math.sin(half) * (1 if i % 2 == 0 else -1)] for i in range(segments)])
    return polyline(np.vstack([np.zeros(2), np.cumsum(length_m * steps, axis=0)]))


@pytest.mark.parametrize("tolerance_mm", [0.01, 0.05, 0.2])
def test_a_zigzag_of_150_degree_turns_is_never_slower_than_exact_stop(tolerance_mm: float) -> None:
    """Blends there brake further ahead than a stop (√(f a R) < √(2 a R tan 75°)): the planner keeps the stops
    or blends only where quicker; the tolerance is used to the path (the blend's distance to the lines is P)."""
    program = zigzag_150()
    exact = Interpolator(program, LIMITS_2).duration_s
    plan = blended(program, tolerance_mm)
    assert plan.duration_s <= exact
    for blend in plan.blended.blends:
        assert blend.deviation_m <= tolerance_mm * 1e-3 * (1 + 1e-12)
    assert worst_deviation_m(plan) <= tolerance_mm * 1e-3 * (1 + 1e-9)


def test_line_blends_use_the_whole_tolerance_measured_to_the_path() -> None:
    """150° turn, P = 50 µm: R (1 - cos 75°) = P, so R = 67.5 µm (measured to the corner point: 17.5 µm); on a
    174° corner the arc's largest distance from the two lines, sampled, is P."""
    radius, _ = corner_trim_m(math.radians(150.0), 5e-5, 1.0)
    assert radius == pytest.approx(5e-5 / (1.0 - math.cos(math.radians(75.0))))
    plan = blend_program(polyline(np.array([[0.0, 0.0], [0.01, 0.0], [0.0, 0.001]])), 5e-5)
    arc = plan.planned.segments[1]
    assert isinstance(arc, ArcSegment)
    deviation = plan.deviation_m(arc.point(np.linspace(0.0, arc.length_m, 2001)))
    assert float(deviation.max()) == pytest.approx(5e-5, rel=1e-6)
