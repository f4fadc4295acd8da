"""The FIR jerk mode streamed (``motion/jerk_stream.py``): a window shorter than the program streams the (v, a)
plan chunk by chunk with the filter behind it, every limit and P held on every 1 ms sample, memory bounded.

Chunks are made small (``MIN_CHUNK_SEGMENTS`` patched) so that the short programs here stream in many of them.
``CNC_JERK_STREAM_EXAMPLES`` sets the hypothesis examples (the test command runs a few).
"""
from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from unittest import mock

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from cnc_contour_control.motion import interpolation, plan_stream
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import LineSegment, Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.reference_check import limit_ratios

EXAMPLES = int(os.environ.get("CNC_JERK_STREAM_EXAMPLES", "5"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
LIMIT_GOAL = 1.0 + 1e-9
PERIOD_S = 1e-3
LIMITS = AxisLimits((2000 / 60000,) * 2, (0.25, 0.25), (10.0, 10.0))
#: Planned segments per chunk and the window: a program of a few dozen segments streams in several chunks.
CHUNK, WINDOW = 8, 6


@contextmanager
def small_chunks(chunk: int = CHUNK) -> Iterator[None]:
    with mock.patch.object(plan_stream, "MIN_CHUNK_SEGMENTS", chunk):
        yield


def _polyline(points: np.ndarray, feed_m_s: float) -> Program:
    segments = tuple(LineSegment(a, b, feed_m_s) for a, b in zip(points[:-1], points[1:]))
    return Program("polyline", ("x", "y"), segments)


def _whole(program: Program, config: InterpolatorConfig) -> Interpolator:
    """The same program planned whole (no stream) with the same window."""
    with mock.patch.object(interpolation, "start_stream", lambda *args: None):
        return Interpolator(program, LIMITS, config)


@st.composite
def polylines(draw: st.DrawFn) -> Program:
    """20-40 segments of 0.3-3 mm turning by up to 150° (a few sharp corners: stops held), at 300-2000 mm/min."""
    n = draw(st.integers(20, 40))
    lengths = draw(st.lists(st.floats(3e-4, 3e-3), min_size=n, max_size=n))
    turns = draw(st.lists(st.floats(-2.6, 2.6), min_size=n, max_size=n))
    heading = np.cumsum(turns)
    steps = np.c_[np.cos(heading), np.sin(heading)] * np.asarray(lengths)[:, None]
    points = np.vstack([np.zeros(2), np.cumsum(steps, axis=0)])
    return _polyline(points, draw(st.floats(0.005, 2000 / 60000)))


#: 21 lines along x, a stop at a 1 rad corner, then a kink of 2.4e-8 rad (under the corner tolerance: passed at
#: 21 mm/s) between lines that accelerate at the y limit: the kink's velocity turn, averaged over the window, took
#: the filtered y acceleration to 1 + 1.2e-8 of the limit before the fir plan kept a reserve for it.
KINK_POINTS = [[0.001953125 * k, 0.0] for k in range(22)] + [
    [0.04141951837709553, 0.0006290266654255336], [0.0424747962964563, 0.002272524696618335],
    [0.04353007421581707, 0.003916022727811136], [0.044585352135177836, 0.005559520759003937]]
#: A generated polyline whose whole plan keeps the program as written (22 segments, 3.168 s) where the stream
#: blends it (28, 3.178 s): the samples differ by up to 0.32 mm, each within the limits and P.
AS_WRITTEN_POINTS = [
    [0.0, 0.0],
    [0.001953125, 0.0],
    [0.00390625, 0.0],
    [0.005859375, 0.0],
    [0.008361557203559349, 0.0],
    [0.010700491803806795, 0.0],
    [0.013487982117835336, 0.0],
    [0.015858983399651305, 0.0],
    [0.016875899298516562, 0.0],
    [0.01834047253449863, 0.0],
    [0.018903576969942836, 0.0016947020321305334],
    [0.01797296268180909, 0.0028473865894657205],
    [0.018815104316181486, 0.004609627984190515],
    [0.019524534908316755, 0.006094162063872485],
    [0.0208229642515248, 0.007303774243492607],
    [0.020474827424084387, 0.009225621795980765],
    [0.018669549340817857, 0.009971053421082976],
    [0.016864271257551328, 0.010716485046185187],
    [0.015058993174284798, 0.011461916671287398],
    [0.013253715091018269, 0.012207348296389609],
    [0.011448437007751739, 0.01295277992149182],
    [0.00964315892448521, 0.01369821154659403],
    [0.00783788084121868, 0.014443643171696241]]


@SETTINGS
@given(program=polylines(), tolerance_mm=st.sampled_from([0.005, 0.02]))
@example(program=_polyline(np.array(KINK_POINTS), 0.03125), tolerance_mm=0.005)
@example(program=_polyline(np.array(AS_WRITTEN_POINTS), 0.015625), tolerance_mm=0.02)
def test_streamed_fir_holds_the_limits_and_p_on_every_sample(program: Program, tolerance_mm: float) -> None:
    config = InterpolatorConfig(path_tolerance_mm=tolerance_mm, clamp_feed=True, jerk_mode="fir",
                                look_ahead_segments=WINDOW)
    with small_chunks():
        streamed = Interpolator(program, LIMITS, config)
        assert streamed._stream is not None and streamed.jerk_mode_used == "fir"
        whole = _whole(program, config)
        times = np.arange(-3 * PERIOD_S, max(streamed.duration_s, whole.duration_s) + 3 * PERIOD_S, PERIOD_S)
        trajectory = streamed.sample_array(times)
    ratios = limit_ratios(trajectory.position_m, PERIOD_S, LIMITS)
    assert ratios.worst() <= LIMIT_GOAL, ratios
    whole_ratios = limit_ratios(whole.sample_array(times).position_m, PERIOD_S, LIMITS)
    assert whole_ratios.worst() <= LIMIT_GOAL, whole_ratios
    deviation_m = program.contour_distance(trajectory.position_m)[0]
    assert deviation_m.max() <= tolerance_mm * 1e-3 * LIMIT_GOAL + 1e-15
    assert trajectory.done[-1] and not trajectory.done[0]
    np.testing.assert_allclose(trajectory.position_m[-1], whole.sample(times[-1]).position_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(trajectory.position_m[-1], program.end_m, rtol=0, atol=1e-12)
    stream = streamed._stream
    # the whole plan keeps the program as written where that is quicker than its blends (a global choice, which a
    # stream, chunk by chunk, cannot make): only the same planned path has the same samples
    same_path = len(streamed.program.segments) == len(whole.program.segments)
    if stream.replanned_chunks == 0 and whole.jerk_filter == streamed.jerk_filter and whole.jerk_mode_used == "fir" \
            and same_path:
        expected = whole.sample_array(times)  # the same caps: the same samples
        np.testing.assert_allclose(trajectory.position_m, expected.position_m, rtol=0, atol=1e-12)
        assert streamed.duration_s == np.float64(whole.duration_s) or abs(streamed.duration_s - whole.duration_s) < 1e-9


def test_a_streamed_fir_plan_holds_a_bounded_number_of_segments_while_sampled() -> None:
    """700 segments sampled every 50 ms while forgetting what is behind the filter: the planned segments held
    stay under a bound set by the chunk and the window, and the samples are those of the same plan kept whole."""
    rng = np.random.default_rng(7)
    heading = np.cumsum(rng.uniform(-0.3, 0.3, 700))
    points = np.vstack([np.zeros(2), np.cumsum(np.c_[np.cos(heading), np.sin(heading)] * 2e-4, axis=0)])
    program = _polyline(points, 0.02)
    config = InterpolatorConfig(path_tolerance_mm=0.01, jerk_mode="fir", look_ahead_segments=WINDOW)
    forget = 32
    with small_chunks(16), mock.patch.object(plan_stream, "FORGET_PHASES", forget):
        streamed, kept = Interpolator(program, LIMITS, config), Interpolator(program, LIMITS, config)
        stream, fir = streamed._stream, streamed.jerk_filter
        assert stream is not None and fir is not None
        held: list[int] = []
        t_s, step_s = 0.0, 50 * PERIOD_S
        while True:
            sample = streamed.sample(t_s)
            if len(held) % 8 == 0:
                np.testing.assert_allclose(sample.position_m, kept.sample(t_s).position_m, rtol=0, atol=1e-12)
            stream.forget_before(t_s - fir.window_s)
            held.append(len(stream._blocks.segments))  # what is kept of the planned segments
            if sample.done:
                break
            t_s += step_s
    bound = 2 * forget + 3 * 16 + WINDOW  # phases gathered before forgetting, the chunks in hand, the window
    assert len(stream.segments) > 5 * bound  # the program is far longer than the bound
    assert max(held) <= bound, max(held)
    assert stream._blocks.base > 0  # it did forget


def test_a_chunks_check_measures_only_against_its_own_programmed_segments() -> None:
    """The check of a chunk's filtered reference looks up the programmed segments its samples come from (a bounded
    number per chunk), not every segment since the program's start: a check that looped from segment 0 made each
    chunk of a 150 000-segment program cost more than the last (0.06 s to 0.6 s of CPU per 1 s of profile)."""
    heading = np.cumsum(np.full(1200, 0.01))
    points = np.vstack([np.zeros(2), np.cumsum(np.c_[np.cos(heading), np.sin(heading)] * 2e-4, axis=0)])
    program = _polyline(points, 0.02)
    config = InterpolatorConfig(path_tolerance_mm=0.01, jerk_mode="fir", look_ahead_segments=WINDOW)
    lookups: list[int] = []
    searchsorted = np.searchsorted

    def counted(*args: object, **kwargs: object) -> object:
        lookups.append(1)
        return searchsorted(*args, **kwargs)

    with small_chunks(16):
        stream = Interpolator(program, LIMITS, config)._stream
        assert stream is not None
        per_chunk = []
        with mock.patch.object(np, "searchsorted", counted):
            while not stream.finished:
                before = len(lookups)
                stream.plan_chunk()
                per_chunk.append(len(lookups) - before)
    assert len(per_chunk) > 40
    assert max(per_chunk[-10:]) <= 2 * max(per_chunk[:10]), per_chunk
