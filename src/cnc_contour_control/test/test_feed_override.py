"""The on-line feed override: ramps within the axis limits, feed hold stops on the path, resume, ratios > 1."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.feed_override import (
    OverrideConfig,
    OverrideFollower,
    hold_distance_m,
    planning_limits,
)
from cnc_contour_control.motion.geometry import LineSegment, Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.program import load_program
from cnc_contour_control.motion.reference_types import ReferenceSample

LIMITS = AxisLimits((0.05, 0.05), (0.5, 0.5))
DT_S = 1e-3


def follower(program: Program, config: OverrideConfig | None = None, limits: AxisLimits = LIMITS) -> OverrideFollower:
    config = config or OverrideConfig()
    return OverrideFollower(Interpolator(program, planning_limits(limits, config)), limits, config)


def run(f: OverrideFollower, requests: list[float], scheduled: int | None = None) -> tuple[np.ndarray, np.ndarray,
                                                                                            list]:
    """Every request in turn; with ``scheduled``, the requests past the first ``scheduled`` only until the program
    is done (a done program holds its end: the rest would repeat that sample)."""
    samples = [f.advance(0.0, requests[0])]
    for index, request in enumerate(requests[1:], start=1):
        if scheduled is not None and index >= scheduled and samples[-1].done:
            break
        samples.append(f.advance(DT_S, request))
    positions = np.array([s.position_m for s in samples])
    ratios = np.array([s.feed_override_ratio for s in samples])
    return positions, ratios, samples


def assert_within_limits(positions: np.ndarray, samples: list, limits: AxisLimits = LIMITS) -> None:
    v_max, a_max = np.asarray(limits.max_velocity_m_s), np.asarray(limits.max_acceleration_m_s2)
    assert np.all(np.abs([s.velocity_m_s for s in samples]) <= v_max * (1 + 1e-9))
    assert np.all(np.abs([s.acceleration_m_s2 for s in samples]) <= a_max * (1 + 1e-9))
    assert np.all(np.abs(np.diff(positions, axis=0) / DT_S) <= v_max * (1 + 1e-9))
    assert np.all(np.abs(np.diff(positions, 2, axis=0) / DT_S**2) <= a_max * (1 + 1e-9))


def line(length_m: float = 0.05, feed_m_s: float = 0.02) -> Program:
    return Program("line", ("x", "y"), (LineSegment([0.0, 0.0], [length_m, 0.0], feed_m_s),))


def test_a_step_in_the_request_ramps_within_the_limits() -> None:
    requests = [1.0] * 400 + [0.3] * 400 + [1.0] * 3000
    positions, ratios, samples = run(follower(line()), requests)
    assert_within_limits(positions, samples)
    assert ratios[399] == 1.0 and ratios[401] > 0.3            # no jump: the ratio ramps down
    assert ratios[700] == pytest.approx(0.3)                     # and gets there
    assert samples[-1].done and positions[-1][0] == pytest.approx(0.05)


class CountingFollower(OverrideFollower):
    """Counts the samples each tick evaluates."""

    evaluations = 0

    def _scaled(self, ratio: float, dt_s: float) -> tuple[ReferenceSample, bool]:
        self.evaluations += 1
        return super()._scaled(ratio, dt_s)


@settings(max_examples=12, deadline=None)
@given(st.floats(0.005, 0.03), st.floats(0.01, 0.05), st.floats(0.05, 2.0))
def test_a_steady_ratio_costs_one_sample_per_tick(length_m: float, feed_m_s: float, a_max: float) -> None:
    """A plan accelerating at the limit, followed at ratio 1: one sample per tick, and the plan's own clock (the
    share of the limit failed there, and each tick bisected 41 samples to find the same one: in a real-time graph
    whose jerk filter steps several times per late tick that cost fed on itself)."""
    limits = AxisLimits((0.05, 0.05), (a_max, a_max))
    f = CountingFollower(Interpolator(line(length_m, feed_m_s), limits), limits, OverrideConfig())
    positions, ratios, samples = run(f, [1.0] * 20_000, scheduled=0)
    assert samples[-1].done and np.all(ratios == 1.0)
    assert f.evaluations == len(samples) - 1, "advance(0) at the start evaluates none"
    clock = [s.profile_time_s for s in samples[:-1]]  # the last: the plan's end, inside its tick
    assert clock == pytest.approx([k * DT_S for k in range(len(clock))], abs=1e-12)
    assert_within_limits(positions, samples, limits)


def test_feed_hold_stops_on_the_path_and_resumes() -> None:
    feed = 0.02
    requests = [1.0] * 600 + [0.0] * 500 + [1.0] * 4000
    positions, ratios, samples = run(follower(line(feed_m_s=feed)), requests)
    assert_within_limits(positions, samples)
    assert np.allclose(positions[:, 1], 0.0)                    # on the path throughout
    held = positions[1099]
    assert ratios[1099] == 0.0 and np.allclose(positions[1050:1100], held)
    travelled_m = held[0] - positions[599][0]
    assert travelled_m <= hold_distance_m(feed, 0.98 * 0.5) * 1.05 + feed * DT_S
    assert samples[-1].done


def test_ratios_above_one_keep_the_limits_when_planned_for() -> None:
    config = OverrideConfig(max_ratio=1.5)
    circle = load_program({"shape": "circle", "radius_mm": 5, "feed_mm_min": 1500})
    requests = [1.5] * 1500 + [0.5] * 500 + [1.5] * 3000
    positions, ratios, samples = run(follower(circle, config), requests)
    assert_within_limits(positions, samples)
    assert ratios.max() == pytest.approx(1.5)
    radius_m = np.hypot(positions[:, 0] - 0.0, positions[:, 1] - 0.005)
    assert np.allclose(radius_m, 0.005, atol=1e-12)             # the circle's points only


def test_requests_beyond_the_range_are_clipped_and_nan_refused() -> None:
    f = follower(line())
    assert f.advance(0.0, 3.0).feed_override_ratio == 1.0
    with pytest.raises(CncError, match="override ratio"):
        f.advance(DT_S, math.nan)


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(1, 300), st.floats(0.0, 1.5)), min_size=1, max_size=8))
def test_random_request_schedules_never_exceed_the_limits(schedule: list) -> None:
    config = OverrideConfig(max_ratio=1.5)
    program = load_program({"shape": "corner", "leg_mm": 5, "feed_mm_min": 1200})
    requests = [r for ticks, r in schedule for _ in range(ticks)]
    positions, _, samples = run(follower(program, config), requests + [1.0] * 3000, scheduled=len(requests))
    assert samples[-1].done
    assert_within_limits(positions, samples)


def zigzag(turn_deg: float, segments: int = 3, length_m: float = 0.001, feed_m_s: float = 0.02) -> Program:
    """Lines alternately up and down along x, turning by ``turn_deg`` at every junction."""
    half = math.radians(0.5 * turn_deg)
    steps = [[math.cos(half), math.sin(half) * (1 if i % 2 == 0 else -1)] for i in range(segments)]
    points = np.vstack([np.zeros(2), np.cumsum(length_m * np.array(steps), axis=0)])
    return Program("zigzag", ("x", "y"), tuple(LineSegment(points[i], points[i + 1], feed_m_s)
                                               for i in range(segments)))


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(turn_deg=st.floats(20.0, 160.0), tolerance_mm=st.floats(0.002, 0.05),
       schedule=st.lists(st.tuples(st.integers(1, 400), st.floats(0.1, 2.0)), min_size=1, max_size=6))
def test_overrides_from_10_to_200_percent_keep_the_tolerance_and_the_limits(
        turn_deg: float, tolerance_mm: float, schedule: list[tuple[int, float]]) -> None:
    """A blended zig-zag planned for 200 %: any schedule of requests in [10 %, 200 %] changed at any tick keeps
    every sample within P of the programmed path and within the velocity and acceleration limits."""
    config = OverrideConfig(max_ratio=2.0)
    program = zigzag(turn_deg)
    interpolator = Interpolator(program, planning_limits(LIMITS, config),
                                InterpolatorConfig(path_tolerance_mm=tolerance_mm, clamp_feed=True))
    f = OverrideFollower(interpolator, LIMITS, config)
    requests = [r for ticks, r in schedule for _ in range(ticks)]
    tail = [requests[-1]] * int(1.2 * interpolator.duration_s / (0.1 * DT_S) + 100)  # to the end at 10 %
    positions, _, samples = run(f, requests + tail, scheduled=len(requests))
    assert samples[-1].done
    assert_within_limits(positions, samples)
    deviation_m = interpolator.blended.local_deviation_m(positions, [s.segment_index for s in samples])
    assert np.max(deviation_m) <= tolerance_mm * 1e-3 * (1 + 1e-9)
