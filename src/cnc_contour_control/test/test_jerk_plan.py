"""The jerk-limited planner mode (``AxisLimits.max_jerk_m_s3``): S-curves, limits on every sample, the path.

Every check differentiates the sampled reference (``reference_check.limit_ratios``: velocity, acceleration and
jerk by finite differences of positions every 1 ms) and measures each sample's exact distance to the
programmed path. ``CNC_JERK_PROGRAMS`` sets the hypothesis examples per kind (the test command runs a few).
"""
from __future__ import annotations

import dataclasses
import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment, Program, Segment
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.jerk_blend import Corner
from cnc_contour_control.motion.jerk_profile import SCurve, peak_speed_m_s, ramp_length_m
from cnc_contour_control.motion.reference_check import limit_ratios, sample_reference

EXAMPLES = int(os.environ.get("CNC_JERK_PROGRAMS", "10"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
LIMIT_GOAL = 1.0 + 1e-9
PERIOD_S = 1e-3
FEED_M_S = 1300 / 60000
LIMITS = AxisLimits((2000 / 60000,) * 2, (0.25, 0.25), (10.0, 10.0))


def _polyline(points: list[tuple[float, float]], feed_m_s: float = FEED_M_S) -> Program:
    segments = tuple(LineSegment(np.array(a, float), np.array(b, float), feed_m_s)
                     for a, b in zip(points[:-1], points[1:]))
    return Program("polyline", ("x", "y"), segments)


def _zigzag(turns: int, side_m: float, turn_deg: float) -> Program:
    """``turns`` sides of ``side_m`` alternating by ``turn_deg`` (the issue's zig-zag: 30 x 5 mm, 150°)."""
    half = math.radians(90.0 - turn_deg / 2.0)
    points = [(0.0, 0.0)]
    for k in range(turns):
        x, y = points[-1]
        points.append((x + side_m * math.sin(half), y + side_m * math.cos(half) * (1 if k % 2 == 0 else -1)))
    return _polyline(points)


def _check(program: Program, limits: AxisLimits, tolerance_mm: float = 0.05) -> Interpolator:
    """Plan, sample every 1 ms and assert every limit and the path tolerance on every sample."""
    config = InterpolatorConfig(path_tolerance_mm=tolerance_mm, clamp_feed=True, jerk_mode="scurve")
    interpolator, trajectory = sample_reference(program, limits, config, PERIOD_S)
    ratios = limit_ratios(trajectory.position_m, PERIOD_S, limits)
    assert ratios.worst() <= LIMIT_GOAL, ratios
    analytic_a = np.abs(trajectory.acceleration_m_s2) / np.asarray(limits.max_acceleration_m_s2)
    assert analytic_a.max() <= LIMIT_GOAL
    deviation_m = program.contour_distance(trajectory.position_m)[0]
    assert deviation_m.max() <= tolerance_mm * 1e-3 + 1e-15   # 1e-15 m: rounding of points on a line
    np.testing.assert_allclose(trajectory.position_m[-1], program.segments[-1].point(program.segments[-1].length_m))
    assert trajectory.done[-1] and not trajectory.done[3]
    stop = Interpolator(program, limits, dataclasses.replace(config, path_tolerance_mm=0.0))
    assert interpolator.duration_s <= stop.duration_s   # never slower than exact stop (under the jerk limit too)
    return interpolator


@pytest.mark.parametrize(("length_m", "speed_m_s", "accel_m_s2", "jerk_m_s3"), [
    (0.1, 0.03, 0.25, 10.0),      # cruises at the feed
    (0.001, 0.03, 0.25, 10.0),    # too short for the feed, acceleration reached
    (1e-5, 0.03, 0.25, 10.0),     # too short to reach the acceleration limit
    (0.05, 0.5, 0.25, 1000.0)])   # large jerk: nearly trapezoidal
def test_s_curve_rest_to_rest_within_limits(length_m: float, speed_m_s: float, accel_m_s2: float,
                                            jerk_m_s3: float) -> None:
    curve = SCurve(length_m, speed_m_s, accel_m_s2, jerk_m_s3)
    times = np.linspace(-0.01, curve.duration_s + 0.01, 20001)
    s, v, a, j = curve.evaluate(times)
    assert s[0] == 0.0 and s[-1] == length_m and v[-1] == 0.0 and a[-1] == 0.0
    assert v.max() <= speed_m_s and np.abs(a).max() <= accel_m_s2 and np.abs(j).max() <= jerk_m_s3
    assert np.all(np.diff(s) >= 0.0)
    middle = curve.evaluate([curve.duration_s / 2.0])[1][0]
    assert middle == pytest.approx(curve.peak_m_s, rel=1e-9)
    if curve.peak_m_s < speed_m_s:   # the ramps take the whole length
        assert 2.0 * ramp_length_m(curve.peak_m_s, accel_m_s2, jerk_m_s3) == pytest.approx(length_m, rel=1e-9)


@pytest.mark.parametrize(("entry_m_s", "exit_m_s", "length_m"), [(0.01, 0.02, 0.01), (0.02, 0.0, 0.005),
                                                                 (0.015, 0.015, 1e-4)])
def test_s_curve_between_speeds(entry_m_s: float, exit_m_s: float, length_m: float) -> None:
    curve = SCurve(length_m, 0.03, 0.25, 10.0, entry_m_s, exit_m_s)
    s, v, a, j = curve.evaluate(np.linspace(0.0, curve.duration_s, 20001))
    assert v[0] == entry_m_s and v[-1] == pytest.approx(exit_m_s, abs=1e-12) and a[0] == 0.0
    assert s[-1] == length_m and abs(a[-2]) < 1e-3 and np.all(np.diff(s) >= 0.0)
    assert v.max() <= 0.03 and np.abs(a).max() <= 0.25 and np.abs(j).max() <= 10.0
    assert np.abs(np.diff(v)).max() < 1e-5   # continuous speed


def test_peak_speed_is_the_feed_where_the_ramps_fit() -> None:
    assert peak_speed_m_s(1.0, 0.03, 0.25, 10.0) == 0.03
    assert peak_speed_m_s(1e-4, 0.03, 0.25, 10.0) < 0.03


def test_issue_zigzag_within_every_limit_and_on_the_path() -> None:
    program = _zigzag(30, 0.005, 150.0)
    interpolator = _check(program, LIMITS)
    unlimited = Interpolator(program, AxisLimits(LIMITS.max_velocity_m_s, LIMITS.max_acceleration_m_s2))
    assert interpolator.duration_s > unlimited.duration_s   # jerk limits cost time; the plan without them differs
    assert interpolator.blended.planned is program


def test_corners_are_passed_at_speed_within_the_tolerance() -> None:
    """At P 0.05 mm the zig-zag's corners are passed at speed (quicker than stopping), the path stays within P
    and uses part of it; at P 0 every corner is an exact stop on the path."""
    program = _zigzag(30, 0.005, 150.0)
    blended = _check(program, LIMITS, 0.05)
    stopping = _check(program, LIMITS, 0.0)
    assert blended.duration_s < stopping.duration_s
    assert blended.junction_speeds_m_s[1:-1].min() > 0.0 and not stopping.junction_speeds_m_s.any()
    positions = blended.sample_array(np.arange(0.0, blended.duration_s, PERIOD_S)).position_m
    assert program.contour_distance(positions)[0].max() > 0.2 * 0.05e-3


def test_corner_deviation_is_the_closed_form() -> None:
    """A corner's farthest point from its two lines is (3 d / 16) sin θ, at its middle."""
    turn = math.radians(120.0)
    u1, u2 = np.array([1.0, 0.0]), np.array([math.cos(turn), math.sin(turn)])
    corner = Corner(np.zeros(2), u1, u2, 0.02, 0.01)
    x, position, velocity, acceleration = corner.evaluate(np.linspace(0.0, corner.duration_s, 2001))
    program = _polyline([(-0.01, 0.0), (0.0, 0.0), (0.01 * u2[0], 0.01 * u2[1])])
    deviation = program.contour_distance(position)[0]
    assert deviation.max() == pytest.approx(3.0 * corner.trim_m / 16.0 * math.sin(turn), rel=1e-6)
    assert x[np.argmax(deviation)] == pytest.approx(0.5, abs=1e-3)
    np.testing.assert_allclose(position[[0, -1]], [-corner.trim_m * u1, corner.trim_m * u2], atol=1e-15)
    np.testing.assert_allclose(acceleration[[0, -1]], 0.0, atol=1e-15)
    assert np.linalg.norm(velocity, axis=1).max() <= 0.02 * (1.0 + 1e-12)


def test_arcs_and_helix_within_every_limit() -> None:
    start, center = np.array([0.02, 0.0, 0.0]), np.zeros(3)
    segments: tuple[Segment, ...] = (
        ArcSegment(start, np.array([0.0, 0.02, 0.001]), center, False, (0, 1), FEED_M_S),
        LineSegment(np.array([0.0, 0.02, 0.001]), np.array([-0.005, 0.02, 0.001]), FEED_M_S),
        ArcSegment(np.array([-0.005, 0.02, 0.001]), np.array([-0.005, 0.0196, 0.001]),
                   np.array([-0.005, 0.0198, 0.0]), True, (0, 1), FEED_M_S))
    program = Program("arcs", ("x", "y", "z"), segments)
    _check(program, AxisLimits((2000 / 60000,) * 3, (0.25,) * 3, (5.0, 10.0, 2.0)))


def test_sample_agrees_with_sample_array() -> None:
    program = _zigzag(4, 0.005, 120.0)
    interpolator = Interpolator(program, LIMITS)
    times = np.linspace(-0.1, interpolator.duration_s + 0.1, 37)
    trajectory = interpolator.sample_array(times)
    for row, t_s in enumerate(times.tolist()):
        sample = interpolator.sample(t_s)
        np.testing.assert_allclose(sample.position_m, trajectory.position_m[row], atol=1e-15)
        np.testing.assert_allclose(sample.velocity_m_s, trajectory.velocity_m_s[row], atol=1e-15)
        assert sample.done == trajectory.done[row]


@pytest.mark.parametrize(("jerk", "message"), [
    ((10.0,), "max_jerk_m_s3 must have one entry per axis (2), got 1"),
    ((10.0, -1.0), "max_jerk_m_s3[1] must be > 0, got -1.0"),
    ((10.0, math.inf), "max_jerk_m_s3[1]")])
def test_jerk_limits_are_validated(jerk: tuple[float, ...], message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")):
        AxisLimits((0.03, 0.03), (0.25, 0.25), jerk)


@st.composite
def _limits(draw: st.DrawFn) -> AxisLimits:
    velocity = draw(st.tuples(*[st.floats(0.005, 0.1)] * 2))
    accel = draw(st.tuples(*[st.floats(0.05, 2.0)] * 2))
    jerk = draw(st.tuples(*[st.floats(1.0, 200.0)] * 2))
    return AxisLimits(velocity, accel, jerk)


@st.composite
def _random_polyline(draw: st.DrawFn) -> Program:
    steps = draw(st.lists(st.tuples(st.floats(-0.01, 0.01), st.floats(-0.01, 0.01)), min_size=1, max_size=8))
    points = [(0.0, 0.0)]
    for dx, dy in steps:
        if math.hypot(dx, dy) > 1e-5:
            points.append((points[-1][0] + dx, points[-1][1] + dy))
    if len(points) < 2:
        points.append((0.001, 0.0))
    return _polyline(points, draw(st.floats(0.002, 0.08)))


@SETTINGS
@given(_random_polyline(), _limits(), st.one_of(st.just(0.0), st.floats(0.001, 0.5)))
def test_random_polylines_keep_every_limit(program: Program, limits: AxisLimits, tolerance_mm: float) -> None:
    _check(program, limits, tolerance_mm)


@SETTINGS
@given(st.integers(2, 12), st.floats(0.0005, 0.01), st.floats(5.0, 175.0), _limits(), st.floats(0.001, 0.5))
def test_random_zigzags_keep_every_limit(turns: int, side_m: float, turn_deg: float, limits: AxisLimits,
                                         tolerance_mm: float) -> None:
    _check(_zigzag(turns, side_m, turn_deg), limits, tolerance_mm)


@st.composite
def _random_chain(draw: st.DrawFn) -> Program:
    """Lines and arcs (circles in xy, helices when z rises) in any order, tangent or not, at one feed."""
    point, segments = np.zeros(3), list[Segment]()
    for _ in range(draw(st.integers(1, 5))):
        if draw(st.booleans()):
            step = np.array([draw(st.floats(-0.01, 0.01)), draw(st.floats(-0.01, 0.01)), 0.0])
            if np.linalg.norm(step) < 1e-4:
                step[0] += 1e-3
            segments.append(LineSegment(point, point + step, FEED_M_S))
        else:
            radius, start_rad = draw(st.floats(5e-4, 0.01)), draw(st.floats(0.0, 2.0 * math.pi))
            sweep = draw(st.floats(math.radians(10.0), math.radians(300.0)))
            clockwise = draw(st.booleans())
            center = point - radius * np.array([math.cos(start_rad), math.sin(start_rad), 0.0])
            end_rad = start_rad - sweep if clockwise else start_rad + sweep
            end = center + radius * np.array([math.cos(end_rad), math.sin(end_rad), 0.0])
            end[2] = point[2] + draw(st.sampled_from([0.0, 0.0, 0.002]))
            segments.append(ArcSegment(point, end, center, clockwise, (0, 1), FEED_M_S))
        point = segments[-1].point(segments[-1].length_m)
    return Program("chain", ("x", "y", "z"), tuple(segments))


@SETTINGS
@given(_random_chain(), st.tuples(*[st.floats(0.01, 0.1)] * 3), st.tuples(*[st.floats(0.05, 2.0)] * 3),
       st.tuples(*[st.floats(1.0, 200.0)] * 3), st.floats(0.001, 0.5))
def test_random_line_and_arc_chains_keep_every_limit(program: Program, velocity: tuple[float, ...],
                                                     accel: tuple[float, ...], jerk: tuple[float, ...],
                                                     tolerance_mm: float) -> None:
    _check(program, AxisLimits(velocity, accel, jerk), tolerance_mm)
