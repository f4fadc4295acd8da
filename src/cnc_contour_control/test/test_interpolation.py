"""The trapezoidal feed profile: durations, stops, limits (property tests), sampling, override."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError, ProgramError
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment, Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.program import load_program
from cnc_contour_control.motion.segment_tangents import end_tangents

LIMITS_2 = AxisLimits((0.035, 0.035), (0.5, 0.5))


def line_program(length_m: float, feed_m_s: float) -> Program:
    return Program("line", ("x", "y"), (LineSegment([0.0, 0.0], [length_m, 0.0], feed_m_s),))


def kink_steps_m_s(interpolator: Interpolator) -> np.ndarray:
    """Per axis, the largest velocity step at a junction passed at speed (m/s): ``v * |T_after - T_before|``.

    A turn under ``corner_angle_tolerance_deg`` is passed without a stop and steps the axis velocities by at most
    ``v * angle`` (:mod:`~cnc_contour_control.motion.interpolation`); the FIR jerk filter spreads that step over
    its window within the limits (its kink reserve), so there it is no allowance (zero).
    """
    n_axes = len(interpolator.limits.max_velocity_m_s)
    if interpolator.jerk_filter is not None or len(interpolator.program.segments) < 2:
        return np.zeros(n_axes)
    start, end = end_tangents(interpolator.program.segments)
    turn = start[1:] - end[:-1]
    speed = interpolator.junction_speeds_m_s[1:-1]
    # the documented bound: |T_after - T_before| = 2 sin(angle / 2) <= angle <= the tolerance
    tolerance_rad = math.radians(interpolator.config.corner_angle_tolerance_deg)
    assert np.all(np.linalg.norm(turn[speed > 0.0], axis=1) <= tolerance_rad * (1 + 1e-9) + 1e-15)
    return np.max(speed[:, None] * np.abs(turn), axis=0)


def check_limits(interpolator: Interpolator, dt_s: float = 2e-4, rtol: float = 1e-7) -> None:
    """Analytic and finite-difference axis velocity and acceleration stay within the limits.

    The finite-difference acceleration may exceed them by a sub-tolerance kink's velocity step over one sample
    (:func:`kink_steps_m_s`), and by 1e-6 m/s² of rounding.
    """
    times = np.arange(-3 * dt_s, interpolator.duration_s + 3 * dt_s, dt_s)
    trajectory = interpolator.sample_array(times)
    v_max = np.asarray(interpolator.limits.max_velocity_m_s)
    a_max = np.asarray(interpolator.limits.max_acceleration_m_s2)
    velocity_fd = np.diff(trajectory.position_m, axis=0) / dt_s
    acceleration_fd = np.diff(trajectory.position_m, 2, axis=0) / dt_s**2
    assert np.all(np.abs(trajectory.velocity_m_s) <= v_max * (1 + rtol))
    assert np.all(np.abs(trajectory.acceleration_m_s2) <= a_max * (1 + rtol))
    assert np.all(np.abs(velocity_fd) <= v_max * (1 + rtol) + 1e-9)
    excess = np.max(np.abs(acceleration_fd) - a_max * (1 + rtol), axis=0)
    assert np.all(excess <= 1e-6 + kink_steps_m_s(interpolator) / dt_s), f"excess over the limits {excess} m/s²"


def test_long_line_is_a_trapezoid() -> None:
    feed, accel, length = 0.02, 0.5, 0.05
    interpolator = Interpolator(line_program(length, feed), LIMITS_2)
    assert interpolator.duration_s == pytest.approx(length / feed + feed / accel)
    assert interpolator.phase_count == 3
    cruise = interpolator.sample(interpolator.duration_s / 2)
    assert cruise.feed_m_s == pytest.approx(feed)
    assert_allclose(cruise.acceleration_m_s2, 0.0, atol=1e-15)
    assert interpolator.sample(0.5 * feed / accel).acceleration_m_s2[0] == pytest.approx(accel)


def test_short_line_is_a_triangle() -> None:
    length = 1e-4
    interpolator = Interpolator(line_program(length, 0.02), LIMITS_2)
    assert interpolator.duration_s == pytest.approx(2 * math.sqrt(length / 0.5))
    peak = interpolator.sample(interpolator.duration_s / 2)
    assert peak.feed_m_s == pytest.approx(math.sqrt(length * 0.5))


def test_start_and_end_samples() -> None:
    program = line_program(0.01, 0.01)
    interpolator = Interpolator(program, LIMITS_2)
    first, after = interpolator.sample(0.0), interpolator.sample(interpolator.duration_s + 1.0)
    assert_allclose(first.position_m, [0.0, 0.0])
    assert_allclose(first.velocity_m_s, 0.0) and not first.done
    assert after.done and after.feed_m_s == 0.0 and after.path_length_m == pytest.approx(0.01)
    assert_allclose(after.position_m, [0.01, 0.0])
    assert_allclose(after.velocity_m_s, 0.0)
    before = interpolator.sample(-1.0)
    assert_allclose(before.position_m, [0.0, 0.0])
    assert_allclose(before.acceleration_m_s2, 0.0) and not before.done
    with pytest.raises(ConfigError, match="t_s must be a number, got nan"):
        interpolator.sample(math.nan)


def test_feed_above_the_axes_projection_is_refused_or_clamped() -> None:
    program = Program("d", ("x", "y"), (LineSegment([0.0, 0.0], [0.03, 0.04], 0.06),))
    limits = AxisLimits((0.03, 1.0), (10.0, 10.0))  # x moves at 0.6 of the feed: at most 0.05 m/s
    with pytest.raises(ProgramError, match=r"segment 0: feed_mm_min must be <= 3000 .* got 3600") as info:
        Interpolator(program, limits)
    assert "axis velocity limits" in str(info.value)
    clamped = Interpolator(program, limits, InterpolatorConfig(clamp_feed=True))
    assert clamped.segment_limits[0].speed_m_s == pytest.approx(0.05)
    check_limits(clamped)


def test_arc_feed_check_uses_the_maximum_over_the_arc() -> None:
    """A quarter arc from angle -90 to 0 has |tangent_x| up to 1 and |tangent_y| up to 1."""
    arc = ArcSegment([0.0, 0.0], [0.02, 0.02], [0.0, 0.02], False, (0, 1), 0.03)
    program = Program("a", ("x", "y"), (arc,))
    with pytest.raises(ProgramError, match=r"segment 0: feed_mm_min must be <= 1200 .*got 1800"):
        Interpolator(program, AxisLimits((1.0, 0.02), (10.0, 10.0)))


def test_circle_speed_obeys_the_centripetal_limit() -> None:
    program = load_program({"shape": "circle", "radius_mm": 20, "feed_mm_min": 1300})
    limits = AxisLimits((0.035, 0.035), (0.01, 0.01))
    config = InterpolatorConfig(arc_centripetal_fraction=0.4, arc_combined_budget=False)
    interpolator = Interpolator(program, limits, config)
    assert interpolator.segment_limits[0].speed_m_s == pytest.approx(math.sqrt(0.4 * 0.01 * 0.02))
    assert interpolator.segment_limits[0].acceleration_m_s2 == pytest.approx(0.6 * 0.01)
    check_limits(interpolator, dt_s=1e-3)


def test_corner_stops_exactly_at_the_corner() -> None:
    program = load_program({"shape": "corner", "leg_mm": 10, "feed_mm_min": 600})
    interpolator = Interpolator(program, LIMITS_2)
    assert_allclose(interpolator.junction_speeds_m_s, 0.0)
    times = np.linspace(0.0, interpolator.duration_s, 20001)
    trajectory = interpolator.sample_array(times)
    at_corner = np.argmin(np.linalg.norm(trajectory.position_m - [0.01, 0.0], axis=1))
    assert trajectory.feed_m_s[at_corner] < 0.5 * (times[1] - times[0]) + 1e-12
    assert interpolator.duration_s == pytest.approx(2 * (0.01 / 0.01 + 0.01 / 0.5))


def tangent_line_arc_program(feed_m_s: float = 0.02) -> Program:
    line = LineSegment([0.0, 0.0], [0.01, 0.0], feed_m_s)
    arc = ArcSegment([0.01, 0.0], [0.02, 0.01], [0.01, 0.01], False, (0, 1), feed_m_s)
    back = LineSegment([0.02, 0.01], [0.02, 0.03], feed_m_s)
    return Program("tangent", ("x", "y"), (line, arc, back))


def test_tangent_junctions_keep_moving() -> None:
    interpolator = Interpolator(tangent_line_arc_program(), LIMITS_2)
    speeds = interpolator.junction_speeds_m_s
    assert speeds[0] == 0.0 and speeds[-1] == 0.0
    assert np.all(speeds[1:-1] > 0.01)
    assert speeds[1] == pytest.approx(interpolator.segment_limits[1].speed_m_s)
    check_limits(interpolator)


def test_corner_tolerance_decides_what_is_tangent() -> None:
    kink = math.radians(0.5)
    segments = (LineSegment([0.0, 0.0], [0.01, 0.0], 0.01),
                LineSegment([0.01, 0.0], [0.02, 0.01 * math.tan(kink)], 0.01))
    program = Program("kink", ("x", "y"), segments)
    assert Interpolator(program, LIMITS_2).junction_speeds_m_s[1] == 0.0
    loose = Interpolator(program, LIMITS_2, InterpolatorConfig(corner_angle_tolerance_deg=1.0))
    assert loose.junction_speeds_m_s[1] == pytest.approx(0.01)


def test_a_turn_under_the_corner_tolerance_steps_the_axis_velocities_by_v_times_the_turn() -> None:
    """The step :func:`check_limits` allows (:func:`kink_steps_m_s`) is the one the samples show, at most v * angle.

    Generated polylines found it (a 0.2 mm line and a 3.9 mm line turning by 0.12 µrad, at 0.5 mm of tolerance):
    the step over 1 ms exceeded the 1e-6 m/s² of rounding the check allowed."""
    heading, turn = 0.23, 1e-6  # rad; the default tolerance is 1e-4 deg = 1.75 µrad
    corner = 0.004 * np.array([math.cos(heading), math.sin(heading)])
    end = corner + 0.004 * np.array([math.cos(heading + turn), math.sin(heading + turn)])
    program = Program("kink", ("x", "y"), (LineSegment([0.0, 0.0], corner, 0.02), LineSegment(corner, end, 0.02)))
    interpolator = Interpolator(program, AxisLimits((0.035, 0.035), (0.5, 0.125)))
    speed = float(interpolator.junction_speeds_m_s[1])
    at_s = float(interpolator._phases.start_s[np.flatnonzero(interpolator._phases.segment == 1)[0]])
    before, after = (interpolator.sample(at_s + d).velocity_m_s for d in (-1e-12, 1e-12))
    steps = kink_steps_m_s(interpolator)
    assert speed > 0.0 and np.all(steps <= speed * turn)
    assert_allclose(np.abs(after - before), steps, rtol=1e-3, atol=1e-15)
    check_limits(interpolator, dt_s=1e-3, rtol=1e-9)


@pytest.mark.parametrize("section", [
    {"shape": "line", "angle_deg": 5, "length_mm": 40, "feed_mm_min": 400},
    {"shape": "line", "angle_deg": 5, "length_mm": 40, "feed_mm_min": 900},
    {"shape": "circle", "radius_mm": 20, "feed_mm_min": 400},
    {"shape": "circle", "radius_mm": 20, "feed_mm_min": 1300},
    {"shape": "corner", "leg_mm": 20, "feed_mm_min": 300},
    {"shape": "corner", "leg_mm": 20, "feed_mm_min": 600},
])
def test_shipped_shapes_respect_the_limits(section: dict) -> None:
    check_limits(Interpolator(load_program(section), LIMITS_2))


@st.composite
def random_programs(draw: st.DrawFn) -> tuple[Program, AxisLimits, InterpolatorConfig]:
    """Chains of lines and arcs (tangent or not; helices in 3 axes) with random feeds and limits."""
    n_axes = draw(st.sampled_from([2, 3]))
    point, heading = np.zeros(n_axes), draw(st.floats(-math.pi, math.pi))
    segments: list[LineSegment | ArcSegment] = []
    for _ in range(draw(st.integers(1, 4))):
        if not draw(st.booleans()):
            heading += draw(st.floats(-math.pi, math.pi))
        feed = draw(st.floats(0.002, 0.05))
        rise = draw(st.floats(-0.005, 0.005)) if n_axes == 3 else 0.0
        if draw(st.booleans()):
            length = draw(st.floats(1e-4, 0.02))
            end = point.copy()
            end[:2] += length * np.array([math.cos(heading), math.sin(heading)])
            end[2:] += rise
            segments.append(LineSegment(point, end, feed))
        else:
            radius, sweep = draw(st.floats(5e-4, 0.02)), draw(st.floats(0.1, 2 * math.pi))
            side = draw(st.sampled_from([1.0, -1.0]))  # +1: ccw, centre on the left
            center = point.copy()
            center[:2] += radius * np.array([-math.sin(heading), math.cos(heading)]) * side
            start_angle = math.atan2(point[1] - center[1], point[0] - center[0])
            end = point.copy()
            end[:2] = center[:2] + radius * np.array([math.cos(start_angle + side * sweep),
                                                       math.sin(start_angle + side * sweep)])
            end[2:] += rise
            if np.hypot(*(end[:2] - point[:2])) < 2e-6 and sweep < math.pi:
                continue
            segments.append(ArcSegment(point, end, center, side < 0, (0, 1), feed))
            heading += side * segments[-1].sweep_rad
        point = segments[-1].end_m
    if not segments:
        segments.append(LineSegment(point, point + 0.001, 0.01))
    v_max = tuple(draw(st.floats(0.005, 0.1)) for _ in range(n_axes))
    a_max = tuple(draw(st.floats(0.05, 2.0)) for _ in range(n_axes))
    config = InterpolatorConfig(arc_centripetal_fraction=draw(st.floats(0.1, 0.9)), clamp_feed=True)
    names = ("x", "y", "z")[:n_axes]
    return Program("random", names, tuple(segments)), AxisLimits(v_max, a_max), config


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_programs())
def test_random_programs_never_exceed_the_axis_limits(case: tuple) -> None:
    program, limits, config = case
    interpolator = Interpolator(program, limits, config)
    dt_s = max(2e-4, interpolator.duration_s / 100_000)
    check_limits(interpolator, dt_s=dt_s)
    end = interpolator.sample(interpolator.duration_s)
    assert end.done and end.path_length_m == pytest.approx(program.total_length_m)


def test_samples_follow_the_geometry_and_the_speed() -> None:
    interpolator = Interpolator(tangent_line_arc_program(), LIMITS_2)
    program = interpolator.program
    dt_s = 1e-5
    times = np.linspace(0.01, interpolator.duration_s - 0.01, 37)
    for t in times:
        sample = interpolator.sample(float(t))
        index = sample.segment_index
        s_local = sample.path_length_m - program.segment_start_m[index]
        assert_allclose(sample.position_m, program.segments[index].point(s_local), atol=1e-15)
        ahead, behind = interpolator.sample(t + dt_s), interpolator.sample(t - dt_s)
        assert_allclose(sample.velocity_m_s, (ahead.position_m - behind.position_m) / (2 * dt_s), atol=1e-6)
        assert np.linalg.norm(sample.velocity_m_s) == pytest.approx(sample.feed_m_s, abs=1e-15)
        assert sample.programmed_feed_m_s == pytest.approx(0.02)


def test_sample_array_matches_sample() -> None:
    interpolator = Interpolator(load_program({"shape": "circle", "radius_mm": 20, "feed_mm_min": 1300}), LIMITS_2)
    times = np.linspace(-0.1, interpolator.duration_s + 0.1, 53)
    trajectory = interpolator.sample_array(times)
    for k, t in enumerate(times):
        sample = interpolator.sample(float(t))
        assert_allclose(trajectory.position_m[k], sample.position_m, atol=1e-15)
        assert_allclose(trajectory.velocity_m_s[k], sample.velocity_m_s, atol=1e-15)
        assert_allclose(trajectory.acceleration_m_s2[k], sample.acceleration_m_s2, atol=1e-12)
        assert trajectory.done[k] == sample.done
        assert trajectory.path_length_m[k] == pytest.approx(sample.path_length_m, abs=1e-15)


def test_advance_at_override_one_equals_sample() -> None:
    interpolator = Interpolator(line_program(0.01, 0.01), LIMITS_2)
    dt_s = 1e-3
    first = interpolator.advance(0.0)
    assert_allclose(first.position_m, [0.0, 0.0])
    for k in range(1, 50):
        stepped = interpolator.advance(dt_s)
        assert_allclose(stepped.position_m, interpolator.sample(k * dt_s).position_m, atol=1e-15)
        assert stepped.feed_override_ratio == 1.0


@pytest.mark.parametrize("ratio", [0.0, 0.25, 0.5, 1.0])
def test_advance_scales_time_velocity_and_acceleration(ratio: float) -> None:
    interpolator = Interpolator(tangent_line_arc_program(), LIMITS_2)
    for _ in range(300):
        sample = interpolator.advance(1e-3, override_ratio=ratio)
    base = interpolator.sample(ratio * 0.3)
    assert interpolator.profile_time_s == pytest.approx(ratio * 0.3)
    assert_allclose(sample.position_m, base.position_m, atol=1e-15)
    assert_allclose(sample.velocity_m_s, ratio * base.velocity_m_s, atol=1e-15)
    assert_allclose(sample.acceleration_m_s2, ratio**2 * base.acceleration_m_s2, atol=1e-15)
    assert sample.feed_m_s == pytest.approx(ratio * base.feed_m_s)
    interpolator.reset()
    assert interpolator.profile_time_s == 0.0


def test_advance_holds_the_end() -> None:
    interpolator = Interpolator(line_program(0.001, 0.01), LIMITS_2)
    while not (sample := interpolator.advance(1e-3, 2.0)).done:
        pass
    assert interpolator.profile_time_s == pytest.approx(interpolator.duration_s)
    assert_allclose(sample.position_m, [0.001, 0.0]) and sample.feed_m_s == 0.0



@pytest.mark.parametrize("kwargs, message", [
    ({"max_velocity_m_s": (0.1, 0.0)}, r"max_velocity_m_s\[1\] must be > 0, got 0.0"),
    ({"max_acceleration_m_s2": (0.1, -2.0)}, r"max_acceleration_m_s2\[1\] must be > 0, got -2.0"),
    ({"max_acceleration_m_s2": (0.1,)}, r"max_acceleration_m_s2 must have one entry per axis \(2\), got 1"),
    ({"max_velocity_m_s": ()}, "max_velocity_m_s must have at least one entry"),
    ({"max_velocity_m_s": 0.1}, "max_velocity_m_s must be a list with one value per axis"),
    ({"max_velocity_m_s": (0.1, math.nan)}, r"max_velocity_m_s\[1\] must be finite"),
])
def test_bad_axis_limits_are_refused(kwargs: dict, message: str) -> None:
    args = {"max_velocity_m_s": (0.1, 0.1), "max_acceleration_m_s2": (1.0, 1.0)}
    args.update(kwargs)
    with pytest.raises(ConfigError, match=message):
        AxisLimits(**args)


@pytest.mark.parametrize("kwargs, message", [
    ({"corner_angle_tolerance_deg": -1.0}, r"corner_angle_tolerance_deg must be in \[0.0, 10.0\], got -1.0"),
    ({"arc_centripetal_fraction": 1.0}, r"arc_centripetal_fraction must be in \[0.01, 0.99\], got 1.0"),
    ({"arc_centripetal_fraction": 0.0}, r"arc_centripetal_fraction must be in \[0.01, 0.99\], got 0.0"),
    ({"clamp_feed": "yes"}, "clamp_feed must be true or false, got 'yes'"),
])
def test_bad_interpolator_config_is_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        InterpolatorConfig(**kwargs)


def test_limits_must_match_the_program_axes() -> None:
    with pytest.raises(ConfigError, match=r"limits must have one entry per program axis \(2: \['x', 'y'\]\), got 3"):
        Interpolator(line_program(0.01, 0.01), AxisLimits((1.0,) * 3, (1.0,) * 3))


@pytest.mark.parametrize("dt_s, ratio, message", [
    (-1e-3, 1.0, "dt_s must be >= 0, got -0.001"),
    (1e-3, -0.5, "override_ratio must be >= 0, got -0.5"),
    (1e-3, math.inf, "override_ratio must be finite"),
])
def test_bad_advance_arguments_are_refused(dt_s: float, ratio: float, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        Interpolator(line_program(0.01, 0.01), LIMITS_2).advance(dt_s, ratio)
