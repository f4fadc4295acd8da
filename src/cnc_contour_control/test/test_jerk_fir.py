"""The FIR jerk mode (``jerk_mode: fir``): the filter against scipy, and every limit and P on every sample.

Limits are checked by finite differences of the positions every 1 ms (``reference_check.limit_ratios``), the
path by each sample's exact distance to the programmed contour. The hypothesis tests draw short programs
(polylines, zig-zags, line-arc chains, 3-axis paths), limits, P and feed override schedules;
``CNC_JERK_FIR_EXAMPLES`` sets their examples (the test command runs a few).
"""
from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig
from cnc_contour_control.motion.geometry import LineSegment, Program, Segment
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.jerk_filter import MovingAverage, filter_taps, moving_average_rows
from cnc_contour_control.motion.reference_check import limit_ratios, sample_reference

EXAMPLES = int(os.environ.get("CNC_JERK_FIR_EXAMPLES", "6"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
LIMIT_GOAL = 1.0 + 1e-9
PERIOD_S = 1e-3
LIMITS = AxisLimits((2000 / 60000,) * 2, (0.25, 0.25), (10.0, 10.0))


@pytest.mark.parametrize("taps", [1, 3, 7])
def test_moving_average_steps_as_scipy_lfilter(taps: int) -> None:
    x = np.random.default_rng(taps).normal(size=(40, 2))
    average = MovingAverage(taps, 2)
    out = np.array([average.step(row) for row in x.tolist()])   # from rest at 0, past every wrap
    np.testing.assert_allclose(out, lfilter(np.ones(taps) / taps, 1.0, x, axis=0), rtol=0, atol=1e-15)
    padded = np.vstack([np.zeros((taps - 1, 2)), x])
    np.testing.assert_allclose(moving_average_rows(padded, taps), out, rtol=0, atol=1e-15)


def test_filter_taps_take_the_largest_axis_need() -> None:
    assert filter_taps(AxisLimits((1.0, 1.0), (0.25, 0.5), (10.0, 10.0)), 1e-3) == 100   # 2 * 0.5 / (10 * 1e-3)
    with pytest.raises(ConfigError, match="max_jerk_m_s3 must be set"):
        filter_taps(AxisLimits((1.0,), (1.0,)), 1e-3)
    with pytest.raises(ConfigError, match="jerk_filter_period_s must be > 0, got 0.0"):
        filter_taps(LIMITS, 0.0)


@pytest.mark.parametrize(("changes", "words"), [({"jerk_mode": "smooth"}, ["jerk_mode", "'fir'", "'smooth'"]),
                                                ({"jerk_filter_period_s": 0.5}, ["jerk_filter_period_s", "0.5"]),
                                                ({"jerk_filter_tolerance_share": 1.0},
                                                 ["jerk_filter_tolerance_share", "1.0"])])
def test_bad_options_are_refused_naming_them(changes: dict[str, object], words: list[str]) -> None:
    with pytest.raises(ConfigError) as caught:
        InterpolatorConfig(**changes)  # type: ignore[arg-type]  # bad values on purpose
    assert all(word in str(caught.value) for word in words), str(caught.value)


def _polyline(points: Sequence[tuple[float, ...]], feed_m_s: float) -> Program:
    segments = tuple(LineSegment(np.array(a, float), np.array(b, float), feed_m_s)
                     for a, b in zip(points[:-1], points[1:]))
    axes = ("x", "y", "z")[:len(points[0])]
    return Program("polyline", axes, segments)


def _check(program: Program, limits: AxisLimits, tolerance_mm: float) -> Interpolator:
    """Every limit and P on every 1 ms sample, the end reached only once the filter has drained."""
    config = InterpolatorConfig(path_tolerance_mm=tolerance_mm, clamp_feed=True, jerk_mode="fir")
    interpolator, trajectory = sample_reference(program, limits, config, PERIOD_S)
    assert interpolator.jerk_filter is not None
    ratios = limit_ratios(trajectory.position_m, PERIOD_S, limits)
    assert ratios.worst() <= LIMIT_GOAL, ratios
    deviation_m = program.contour_distance(trajectory.position_m)[0]
    assert deviation_m.max() <= tolerance_mm * 1e-3 * LIMIT_GOAL + 1e-15
    end = program.segments[-1].point(program.segments[-1].length_m)
    np.testing.assert_allclose(trajectory.position_m[-1], end, rtol=0, atol=1e-15)
    not_there = np.linalg.norm(trajectory.position_m - end, axis=1) > 1e-12
    assert not trajectory.done[not_there].any() and trajectory.done[-1]
    return interpolator


def test_filter_lengthens_the_plan_by_its_window_and_agrees_sample_by_sample() -> None:
    program = _polyline([(0.0, 0.0), (0.01, 0.0), (0.01, 0.005)], 0.02)
    interpolator = _check(program, LIMITS, 0.01)
    fir = interpolator.jerk_filter
    assert fir is not None and fir.taps == 50
    plain = Interpolator(program, LIMITS, InterpolatorConfig(path_tolerance_mm=0.01, jerk_mode="scurve"))
    assert interpolator.duration_s > fir.window_s and plain.duration_s > 0.0
    times = np.linspace(-0.01, interpolator.duration_s + 0.01, 23)
    trajectory = interpolator.sample_array(times)
    for row, t_s in enumerate(times.tolist()):
        sample = interpolator.sample(t_s)
        np.testing.assert_allclose(sample.position_m, trajectory.position_m[row], rtol=0, atol=1e-15)
        assert sample.done == trajectory.done[row]


@st.composite
def _limits(draw: st.DrawFn, n_axes: int = 2) -> AxisLimits:
    velocity = draw(st.tuples(*[st.floats(0.01, 0.05)] * n_axes))
    accel = draw(st.tuples(*[st.floats(0.1, 1.0)] * n_axes))
    jerk = draw(st.tuples(*[st.floats(5.0, 100.0)] * n_axes))
    return AxisLimits(velocity, accel, jerk)


@st.composite
def _random_polyline(draw: st.DrawFn, n_axes: int = 2) -> Program:
    steps = draw(st.lists(st.tuples(*[st.floats(-0.004, 0.004)] * n_axes), min_size=1, max_size=6))
    points = [(0.0,) * n_axes]
    for step in steps:
        if math.hypot(*step) > 1e-4:
            points.append(tuple(p + d for p, d in zip(points[-1], step)))
    if len(points) < 2:
        points.append((0.001,) + (0.0,) * (n_axes - 1))
    return _polyline(points, draw(st.floats(0.005, 0.04)))


@SETTINGS
@given(_random_polyline(), _limits(), st.floats(0.002, 0.1))
def test_random_polylines_keep_every_limit_and_p(program: Program, limits: AxisLimits, tolerance_mm: float) -> None:
    _check(program, limits, tolerance_mm)


@SETTINGS
@given(_random_polyline(3), _limits(3), st.floats(0.002, 0.1))
def test_random_3_axis_paths_keep_every_limit_and_p(program: Program, limits: AxisLimits,
                                                    tolerance_mm: float) -> None:
    _check(program, limits, tolerance_mm)


@SETTINGS
@given(st.integers(2, 8), st.floats(0.001, 0.005), st.floats(5.0, 175.0), _limits(), st.floats(0.002, 0.1))
def test_random_zigzags_keep_every_limit_and_p(turns: int, side_m: float, turn_deg: float, limits: AxisLimits,
                                               tolerance_mm: float) -> None:
    half = math.radians(90.0 - turn_deg / 2.0)
    points = [(0.0, 0.0)]
    for k in range(turns):
        x, y = points[-1]
        points.append((x + side_m * math.sin(half), y + side_m * math.cos(half) * (1 if k % 2 == 0 else -1)))
    _check(_polyline(points, 0.03), limits, tolerance_mm)


@st.composite
def _arc_chain(draw: st.DrawFn) -> Program:
    """Arcs of random radius and sweep, each tangent to the one before or turned, with a helix rise sometimes."""
    point, heading = np.zeros(3), 0.0
    segments: list[Segment] = []
    for _ in range(draw(st.integers(1, 4))):
        radius, sweep = draw(st.floats(0.001, 0.02)), draw(st.floats(0.2, 2.5))
        clockwise, rise = draw(st.booleans()), draw(st.sampled_from([0.0, 0.0005]))
        side = -1.0 if clockwise else 1.0
        center = point + radius * np.array([-math.sin(heading) * side, math.cos(heading) * side, 0.0])
        angle = math.atan2(point[1] - center[1], point[0] - center[0]) + side * sweep
        end = center + radius * np.array([math.cos(angle), math.sin(angle), 0.0]) + np.array([0.0, 0.0, rise])
        segments.append(ArcSegment(point, end, center, clockwise, (0, 1), 0.03))
        point, heading = end, heading + side * sweep + draw(st.sampled_from([0.0, 0.0, 0.6]))
        segments.append(LineSegment(point, point + 0.002 * np.array([math.cos(heading), math.sin(heading), 0.0]),
                                    0.03))
        point = segments[-1].end_m
    return Program("arcs", ("x", "y", "z"), tuple(segments))


@SETTINGS
@given(_arc_chain(), _limits(3), st.floats(0.002, 0.1))
def test_random_arc_chains_keep_every_limit_and_p(program: Program, limits: AxisLimits, tolerance_mm: float) -> None:
    _check(program, limits, tolerance_mm)


@SETTINGS
@given(_random_polyline(), _limits(), st.floats(0.002, 0.1),
       st.lists(st.sampled_from([0.1, 0.5, 1.0, 1.5, 2.0]), min_size=1, max_size=4), st.floats(0.05, 0.4))
def test_override_schedules_keep_every_limit_and_p(program: Program, limits: AxisLimits, tolerance_mm: float,
                                                   ratios: list[float], every_s: float) -> None:
    """The live reference under a schedule of ratios up to 2 (planned for 2): the ramps come out jerk-limited."""
    config = OverrideConfig(max_ratio=2.0, schedule_times_s=tuple(every_s * k for k in range(len(ratios))),
                            schedule_ratios=tuple(ratios))
    live = LiveReference(program, limits, InterpolatorConfig(path_tolerance_mm=tolerance_mm, clamp_feed=True,
                                                             jerk_mode="fir"), config)
    positions, end = [], program.segments[-1].point(program.segments[-1].length_m)
    for tick in range(200_000):
        sample = live.step(tick * 1_000_000, live.request(tick * 1_000_000, 1.0))
        positions.append(sample.position_m)
        if sample.done:
            break
    p = np.array(positions + [positions[-1]] * 3)
    assert sample.done and np.allclose(p[-1], end, rtol=0, atol=1e-15)
    assert limit_ratios(p, PERIOD_S, limits).worst() <= LIMIT_GOAL
    assert program.contour_distance(p)[0].max() <= tolerance_mm * 1e-3 * LIMIT_GOAL + 1e-15


@pytest.mark.parametrize("tick_ns", [1_000_000, 10_000_000])
def test_live_reference_is_done_only_once_the_filter_has_drained(tick_ns: int) -> None:
    """At 1 ms and 10 ms ticks (the filter's period the tick's): ``done`` (the end of a run or goal) comes with the
    end point, n - 1 ticks after the retimed plan's end, n = ceil(2 amax / (jmax T))."""
    program = _polyline([(0.0, 0.0), (0.004, 0.0)], 0.02)
    config = InterpolatorConfig(path_tolerance_mm=0.01, jerk_mode="fir", jerk_filter_period_s=tick_ns * 1e-9)
    live = LiveReference(program, LIMITS, config, OverrideConfig())
    fir = live.interpolator.jerk_filter
    assert fir is not None
    plan_end_s, samples, plan_done = live.interpolator.duration_s - fir.window_s, [], None
    for tick in range(5000):
        samples.append(live.step(tick * tick_ns, 1.0))
        if plan_done is None and live.follower.profile_time_s >= plan_end_s:
            plan_done = tick
        if samples[-1].done:
            break
    taps = math.ceil(2 * 0.25 / (10.0 * tick_ns * 1e-9))
    done = [s.done for s in samples]
    first_done = done.index(True)
    assert samples[first_done].position_m[0] == pytest.approx(0.004, abs=1e-15)
    # short of the end (not drained): by 1e-15 m only, the plan's end a fraction of a µs past a tick (the
    # acceleration's kink reserve, jerk_fir.kink_acceleration_m_s2, takes it off the grid)
    assert samples[first_done - 1].position_m[0] < 0.004
    assert abs(samples[first_done].velocity_m_s).max() < 1e-12
    positions = np.array([s.position_m for s in samples])
    period_s = tick_ns * 1e-9
    assert np.abs(np.diff(positions, 3, axis=0)).max() / period_s**3 <= 10.0 * LIMIT_GOAL
    assert plan_done is not None and first_done - plan_done == taps - 1


def _polygon(sides: int, radius_m: float = 0.02) -> Program:
    angles = np.linspace(0.0, 2.0 * math.pi, sides + 1)
    points = [(radius_m * math.cos(a), radius_m * math.sin(a)) for a in angles.tolist()]
    return _polyline(points[:-1] + [points[0]], 2000 / 60000)


def test_fir_passes_the_36_gon_within_1_15_of_the_feed_bound_pushing_its_corners_out() -> None:
    """The blending bench's 36-gon (R 20 mm, 1300 mm/min, 250 mm/s², 10 m/s³, P 0.01 mm): the window's mean cuts
    its 10-degree corners from outside (``jerk_fir.pushed_corners``), within 1.15 of a bound no plan beats (the
    perimeter at the feed, plus the start and stop at the diagonal's tangential acceleration); limits and P held."""
    feed_m_s = 1300 / 60000
    program = _polyline([(0.02 * math.cos(a), 0.02 * math.sin(a))
                         for a in np.linspace(0.0, 2.0 * math.pi, 37).tolist()[:-1] + [0.0]], feed_m_s)
    interpolator = _check(program, LIMITS, 0.01)
    assert interpolator.jerk_filter is not None and interpolator.jerk_filter.push_m > 0.0
    perimeter_m = sum(segment.length_m for segment in program.segments)
    bound_s = perimeter_m / feed_m_s + feed_m_s / (math.sqrt(2.0) * 0.25)
    assert interpolator.duration_s <= 1.15 * bound_s, (interpolator.duration_s, bound_s)


@pytest.mark.parametrize(("program", "expected"), [(_polyline([(0.02 * math.cos(math.radians(10.0 * k)),
                                                                0.02 * math.sin(math.radians(10.0 * k)))
                                                               for k in range(4)], 2000 / 60000), "scurve"),
                                                   (_polyline([(0.01 * k, 0.0027 * (k % 2)) for k in range(8)],
                                                              2000 / 60000), "fir")])
def test_quickest_runs_the_quicker_mode_and_says_which(program: Program, expected: str) -> None:
    """``jerk_mode`` quickest (the default is fir, whose override ramps keep the jerk limit): three sides of the
    36-gon (its two 10-degree corners next to the ends, which fir does not push out) are quicker as S-curves, a
    zig-zag's 30-degree turns through the filter; every limit and P held, done only at the end point."""
    assert InterpolatorConfig().jerk_mode == "fir"
    config = InterpolatorConfig(path_tolerance_mm=0.01, clamp_feed=True, jerk_mode="quickest")
    interpolator, trajectory = sample_reference(program, LIMITS, config, PERIOD_S)
    durations_s = {mode: Interpolator(program, LIMITS, InterpolatorConfig(path_tolerance_mm=0.01, clamp_feed=True,
                                                                          jerk_mode=mode)).duration_s
                   for mode in ("fir", "scurve")}
    assert interpolator.jerk_mode_used == expected and (interpolator.jerk_filter is not None) is (expected == "fir")
    assert interpolator.duration_s == min(durations_s.values()) < max(durations_s.values())
    assert limit_ratios(trajectory.position_m, PERIOD_S, LIMITS).worst() <= LIMIT_GOAL
    assert program.contour_distance(trajectory.position_m)[0].max() <= 0.01e-3 * LIMIT_GOAL
    end = program.segments[-1].point(program.segments[-1].length_m)
    not_there = np.linalg.norm(trajectory.position_m - end, axis=1) > 1e-12
    assert not trajectory.done[not_there].any() and trajectory.done[-1]


def test_quickest_runs_fir_above_the_compared_length_and_names_a_mode_only_with_a_jerk_limit() -> None:
    program = _polygon(36)
    short = InterpolatorConfig(path_tolerance_mm=0.01, jerk_mode="quickest", jerk_compare_max_segments=35)
    assert Interpolator(program, LIMITS, short).jerk_mode_used == "fir"
    assert Interpolator(program, LIMITS, InterpolatorConfig(jerk_mode="fir")).jerk_mode_used == "scurve", "P 0"
    assert Interpolator(program, AxisLimits(LIMITS.max_velocity_m_s, LIMITS.max_acceleration_m_s2),
                        InterpolatorConfig(path_tolerance_mm=0.01)).jerk_mode_used is None
    with pytest.raises(ConfigError, match="jerk_compare_max_segments must be a whole number, got 2.5"):
        InterpolatorConfig(jerk_compare_max_segments=2.5)  # type: ignore[arg-type]  # a bad value on purpose
