"""Streaming planning (``plan_stream``): a window shorter than the program plans it a chunk at a time."""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError, ProgramError
from cnc_contour_control.motion import interpolation, plan_stream
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import Dwell, Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.testing import WAIT_FLOOR_S, sibling_module
from cnc_tools.bench.blending_corpus import CORPUS
from cnc_tools.bench.blending_limits import bench_config, limits_for

_BLENDING = sibling_module(Path(__file__).parents[2] / "cnc_contour_control" / "test" / "test_blending.py",
                           "test_blending")
SAMPLE_S = 1e-3
#: Programs longer than a chunk (so that the stream plans several), from the bench's corpus and random chains
#: (300 segments, about 600 planned with their blends: ten chunks of :func:`short_chunks`).
PROGRAMS: dict[str, Callable[[], Program]] = {
    "circle-3600-gon": CORPUS["circle-3600-gon"][0], "pocket": CORPUS["pocket"][0],
    "raster-3axis": CORPUS["raster-3axis"][0],
    "random-xy": lambda: _BLENDING.random_chain(np.random.default_rng(1), ("x", "y"), (0, 1), n=300),
    "random-xz": lambda: _BLENDING.random_chain(np.random.default_rng(2), ("x", "y", "z"), (0, 2), n=300)}
CONFIGS = {"bench": bench_config(), "split": InterpolatorConfig(path_tolerance_mm=0.01),
           "exact stop": InterpolatorConfig()}


@pytest.fixture(autouse=True)
def short_chunks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Chunks of 64 planned segments (1024 in use): every program here is planned in many chunks."""
    monkeypatch.setattr(plan_stream, "MIN_CHUNK_SEGMENTS", 64)


def whole_plan(program: Program, limits: AxisLimits, config: InterpolatorConfig,
               monkeypatch: pytest.MonkeyPatch) -> Interpolator:
    """The plan of today's planner (whole program at construction) with the same window."""
    with monkeypatch.context() as patch:
        patch.setattr(interpolation, "start_stream", lambda *args: None)
        return Interpolator(program, limits, config)


def assert_same_samples(streamed: Interpolator, whole: Interpolator, times_s: np.ndarray) -> None:
    a, b = streamed.sample_array(times_s), whole.sample_array(times_s)
    assert_allclose(a.position_m, b.position_m, rtol=0.0, atol=1e-12)
    assert_allclose(a.velocity_m_s, b.velocity_m_s, rtol=0.0, atol=1e-10)
    assert_allclose(a.path_length_m, b.path_length_m, rtol=0.0, atol=1e-12)
    assert np.array_equal(a.done, b.done)


#: Each program with both configurations and both windows, each (configuration, window) pair on three programs
#: (the cheap raster with all four): 12 cases, not the 20 of the full product, which cost 28 % of the core tier.
EQUALITY_CASES = [("circle-3600-gon", "bench", 1), ("circle-3600-gon", "split", 40),
                  ("pocket", "bench", 40), ("pocket", "split", 1),
                  ("raster-3axis", "bench", 1), ("raster-3axis", "bench", 40),
                  ("raster-3axis", "split", 1), ("raster-3axis", "split", 40),
                  ("random-xy", "bench", 40), ("random-xy", "split", 1),
                  ("random-xz", "bench", 1), ("random-xz", "split", 40)]


@pytest.mark.parametrize(("program_name", "config_name", "window"), EQUALITY_CASES)
def test_streaming_equals_the_whole_plan_with_the_same_window(program_name: str, config_name: str, window: int,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    program = PROGRAMS[program_name]()
    limits, config = limits_for(program), dataclasses.replace(CONFIGS[config_name], look_ahead_segments=window)
    streamed, whole = Interpolator(program, limits, config), whole_plan(program, limits, config, monkeypatch)
    assert streamed._stream is not None and whole._stream is None
    times = np.arange(-2 * SAMPLE_S, whole.duration_s + 3 * SAMPLE_S, SAMPLE_S)
    assert_same_samples(streamed, whole, times)  # sampled first: planned lazily up to the end
    assert streamed.duration_s == pytest.approx(whole.duration_s, rel=1e-12)
    # The whole plan's look-ahead caps are differences of one cumulative sum over the program: their squares round
    # to ~eps times the program's total 2 a L (up to 1.3e-13 m/s, 6e-10 relative, with a window of 1); a chunk's
    # sum is over the chunk only. So the speeds' squares agree to a few eps of that total.
    lengths = np.array([segment.length_m for segment in whole.program.segments])
    total_reach = float(np.sum(2.0 * whole.speed_bands.accel_m_s2[:, -1] * lengths))
    assert_allclose(streamed.junction_speeds_m_s ** 2, whole.junction_speeds_m_s ** 2, rtol=1e-12,
                    atol=64 * np.finfo(float).eps * total_reach)


@pytest.mark.parametrize("program_name", ["pocket", "random-xy", "random-xz"])
def test_streaming_stays_within_the_limits_and_the_tolerance(program_name: str) -> None:
    program = PROGRAMS[program_name]()
    streamed = Interpolator(program, limits_for(program), dataclasses.replace(bench_config(), look_ahead_segments=8))
    _BLENDING.check_limits(streamed, dt_s=SAMPLE_S)
    trajectory = streamed.sample_array(np.arange(0.0, streamed.duration_s + SAMPLE_S, SAMPLE_S))
    # the distance from the programmed segments each sample's planned segment comes from: an upper bound of the
    # exact contour distance (test_blending), 1/10 of its cost on these programs
    deviation_m = streamed.blended.local_deviation_m(trajectory.position_m, trajectory.segment_index)
    assert np.max(deviation_m) <= bench_config().path_tolerance_mm * 1e-3 + 1e-12


def test_the_constructor_plans_one_chunk_and_advance_extends_it(monkeypatch: pytest.MonkeyPatch) -> None:
    program = CORPUS["circle-3600-gon"][0]()
    config = dataclasses.replace(bench_config(), look_ahead_segments=50)
    streamed, whole = Interpolator(program, limits_for(program), config), whole_plan(program, limits_for(program),
                                                                                    config, monkeypatch)
    stream = streamed._stream
    assert stream.committed_segments == plan_stream.MIN_CHUNK_SEGMENTS and not stream.finished
    assert len(stream.segments) < len(whole.program.segments) // 4  # blended only what the first window needs
    committed = []
    for _ in range(int(whole.duration_s / 0.01) + 2):
        sample = streamed.advance(0.01)
        expected = whole.sample(min(streamed.profile_time_s, whole.duration_s))
        assert_allclose(sample.position_m, expected.position_m, rtol=0.0, atol=1e-12)
        committed.append(stream.committed_segments)
    assert sample.done and np.all(np.diff(committed) >= 0) and len(set(committed)) > 5


def test_committed_phases_never_change() -> None:
    program = PROGRAMS["random-xy"]()
    streamed = Interpolator(program, limits_for(program), dataclasses.replace(bench_config(), look_ahead_segments=5))
    stream = streamed._stream
    first = (list(stream.start_s), list(stream.v0_m_s), list(stream.junction_speeds_m_s))
    streamed.sample(stream.planned_until_s + 1.0)
    assert len(stream.start_s) > len(first[0])
    assert (stream.start_s[:len(first[0])], stream.v0_m_s[:len(first[1])],
            stream.junction_speeds_m_s[:len(first[2])]) == first


@pytest.mark.parametrize("config_name", list(CONFIGS))
def test_dwells_in_later_chunks_are_planned_as_the_whole_plan(config_name: str,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    base = _BLENDING.polygon(900)
    program = Program("dwells", base.axis_names, base.segments,
                      (Dwell(400, 0.25), Dwell(401, 0.5), Dwell(899, 0.1), Dwell(900, 0.3)))
    limits, config = limits_for(program), dataclasses.replace(CONFIGS[config_name], look_ahead_segments=10)
    streamed, whole = Interpolator(program, limits, config), whole_plan(program, limits, config, monkeypatch)
    times = np.arange(0.0, whole.duration_s + 2 * SAMPLE_S, SAMPLE_S)
    assert_same_samples(streamed, whole, times)
    assert streamed.duration_s == pytest.approx(whole.duration_s, rel=1e-12)


def test_a_window_as_long_as_the_program_is_todays_plan_exactly() -> None:
    program = _BLENDING.polygon(360)
    whole = Interpolator(program, limits_for(program), bench_config())
    planned = len(whole.program.segments)
    same = Interpolator(program, limits_for(program), dataclasses.replace(bench_config(),
                                                                          look_ahead_segments=planned))
    assert same._stream is None
    assert np.array_equal(same.junction_speeds_m_s, whole.junction_speeds_m_s)
    assert same.duration_s == whole.duration_s


def test_a_window_of_zero_segments_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"look_ahead_segments must be in \[1(\.0)?, 1000000000(\.0)?\], got 0"):
        InterpolatorConfig(look_ahead_segments=0)


def test_a_feed_over_the_limit_is_refused_when_the_stream_reaches_it(monkeypatch: pytest.MonkeyPatch) -> None:
    base = _BLENDING.polygon(900)
    fast = dataclasses.replace(base.segments[800], feed_m_s=1.0)  # 60000 mm/min: over 2000 mm/min
    program = Program("late", base.axis_names, base.segments[:800] + (fast,) + base.segments[801:])
    # exact stop: with blends, this polygon's 0.14 mm sides are trimmed away and the fast feed with them
    limits, config = limits_for(program), InterpolatorConfig(look_ahead_segments=10)
    with pytest.raises(ProgramError) as whole_error:
        whole_plan(program, limits, config, monkeypatch)
    streamed = Interpolator(program, limits, config)  # plans the first chunk only: the segment is not yet read
    with pytest.raises(ProgramError) as streamed_error:
        streamed.sample(1e3)
    assert str(streamed_error.value) == str(whole_error.value)
    assert "feed_mm_min must be <=" in str(streamed_error.value)


def test_a_feed_override_follows_a_streaming_plan_without_finishing_it(monkeypatch: pytest.MonkeyPatch) -> None:
    from cnc_contour_control.motion.feed_override import OverrideFollower

    program = CORPUS["circle-3600-gon"][0]()
    limits = limits_for(program)
    config = dataclasses.replace(bench_config(), look_ahead_segments=50)
    streamed = OverrideFollower(Interpolator(program, limits, config), limits)
    whole = OverrideFollower(whole_plan(program, limits, config, monkeypatch), limits)
    ratios = [1.0] * 100 + [0.4] * 300 + [1.2] * 500
    for tick, ratio in enumerate(ratios):
        ours, theirs = streamed.advance(0.01, ratio), whole.advance(0.01, ratio)
        assert_allclose(ours.position_m, theirs.position_m, rtol=0.0, atol=1e-12)
        if tick == 100:  # 1 s into a 5.9 s circle: the follower extended the plan, it did not finish it
            assert not streamed.interpolator._stream.finished
    assert ours.done and theirs.done


def test_a_live_reference_plans_in_a_thread_and_forgets_behind_the_tool(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every tick's sample equals the whole plan's; the planner's thread forgot what was behind the tool (its held
    entries at the end are a fraction of the program's) and ended with the plan."""
    from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig, OverrideFollower

    monkeypatch.setattr(plan_stream, "FORGET_PHASES", 64)
    program = CORPUS["circle-360-gon"][0]()
    limits, config = limits_for(program), dataclasses.replace(bench_config(), look_ahead_segments=50)
    live = LiveReference(program, limits, config, OverrideConfig())
    whole = OverrideFollower(whole_plan(program, limits, config, monkeypatch), limits)
    assert live.planner is not None
    sample = live.step(0, 1.0)
    expected = whole.advance(0.0, 1.0)
    for tick in range(1, 10_000):
        sample, expected = live.step(tick * 1_000_000, 1.0), whole.advance(1e-3, 1.0)
        assert_allclose(sample.position_m, expected.position_m, rtol=0.0, atol=1e-12)
        if sample.done:
            break
    assert sample.done and expected.done
    live.planner.thread.join(WAIT_FLOOR_S)  # ends as soon as the thread does; the bound only ends a hang
    assert not live.planner.thread.is_alive()
    stream, planned = live.planner.stream, len(whole.interpolator.program.segments)
    assert stream.committed_segments == planned
    # How much is forgotten by the end depends on where the tool was when the thread woke for its last chunk
    # (a loaded machine wakes it later, so it forgets more): at least a third of the program is behind it.
    assert stream._blocks.base >= planned // 3 and len(stream.start_s) < 2 * whole.interpolator.phase_count // 3


def test_a_segment_refused_in_the_planner_s_thread_is_raised_at_the_tick(monkeypatch: pytest.MonkeyPatch) -> None:
    from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig

    program = _BLENDING.polygon(900)
    fast = dataclasses.replace(program.segments[200], feed_m_s=1.0)  # past the first chunk's blocks (128 segments)
    program = Program(program.name, program.axis_names, program.segments[:200] + (fast,) + program.segments[201:])
    live = LiveReference(program, limits_for(program), InterpolatorConfig(look_ahead_segments=10), OverrideConfig())
    assert live.planner is not None and live.planner.stream.committed_segments < 200
    with pytest.raises(ProgramError, match="feed_mm_min must be <="):
        for tick in range(100_000):
            live.step(tick * 10_000_000, 1.0)
