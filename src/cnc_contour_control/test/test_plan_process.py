"""A streamed plan planned in a child process (``motion/plan_process.py``): the same samples as the thread's, the
child's errors and death raised at the tick, the child ended with the plan; segments cross bit for bit.

Chunks are made small (``MIN_CHUNK_SEGMENTS`` patched here; the child plans with its parent's chunk size) so that
a program of a few hundred segments streams in many chunks, most of them planned by the child.
"""
from __future__ import annotations

import dataclasses
import math
import os
import pickle
import signal
from collections.abc import Iterator
from typing import Any
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_contour_control.core.errors import FaultError, ProgramError
from cnc_contour_control.motion import plan_background, plan_process, plan_stream
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig
from cnc_contour_control.motion.geometry import LineSegment, Program
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.segment_codec import decode_segments, encode_segments
from cnc_contour_control.testing import WAIT_FLOOR_S, sibling_module

LIMITS = AxisLimits((2000 / 60000,) * 2, (0.25, 0.25), (10.0, 10.0))
FIR = InterpolatorConfig(path_tolerance_mm=0.01, clamp_feed=True, jerk_mode="fir", look_ahead_segments=6)
TICK_NS = 1_000_000


@pytest.fixture(autouse=True)
def small_chunks(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(plan_stream, "MIN_CHUNK_SEGMENTS", 16)


def zigzag(n: int, feed_m_s: float = 0.02) -> Program:
    """``n`` lines of 1 mm turning by ±30° and, every seventh, 120° (a stop held)."""
    turns = np.where(np.arange(n) % 7 == 6, 2.1, np.where(np.arange(n) % 2, 0.5, -0.5))
    heading = np.cumsum(turns)
    points = np.vstack([np.zeros(2), np.cumsum(1e-3 * np.c_[np.cos(heading), np.sin(heading)], axis=0)])
    return Program("zigzag", ("x", "y"), tuple(LineSegment(a, b, feed_m_s) for a, b in zip(points[:-1], points[1:])))


def live(program: Program, planner: str, wait_ready: bool = True, clamp_feed: bool = True) -> LiveReference:
    config = dataclasses.replace(FIR, stream_planner=planner, clamp_feed=clamp_feed)
    reference = LiveReference(program, LIMITS, config, OverrideConfig())
    assert reference.planner is not None
    if wait_ready and planner == "process":
        remote = reference.planner.remote  # type: ignore[attr-defined]  # a ProcessPlanner's
        assert remote.ready.wait(WAIT_FLOOR_S), remote.failure  # a bound that only ends a hang
    return reference


def run(reference: LiveReference, max_ticks: int = 200_000) -> Iterator[Any]:
    for tick in range(max_ticks):
        sample = reference.step(tick * TICK_NS, 1.0)
        yield sample
        if sample.done:
            return
    raise AssertionError(f"not done within {max_ticks} ticks")


def test_the_child_plans_what_the_thread_plans_sample_for_sample_and_ends_with_the_plan() -> None:
    program = zigzag(240)
    by_process, by_thread = live(program, "process"), live(program, "thread")
    process_samples = [s.position_m for s in run(by_process)]
    thread_samples = [s.position_m for s in run(by_thread)]
    assert len(process_samples) == len(thread_samples) > 5000
    np.testing.assert_allclose(np.array(process_samples), np.array(thread_samples), rtol=0.0, atol=1e-12)
    planner = by_process.planner
    assert isinstance(planner, plan_process.ProcessPlanner)
    assert planner.received_chunks > 10, "the child planned most chunks"
    assert planner.stream.finished and planner.stream.committed_segments == by_thread.planner.stream.committed_segments
    planner.thread.join(WAIT_FLOOR_S)  # ends with the plan; the bound only ends a hang
    assert not planner.thread.is_alive() and planner.remote.exit_code == 0
    assert planner.status_values()["plan_process"].startswith("pid ")


def test_a_segment_the_limits_refuse_in_the_child_is_raised_at_the_tick() -> None:
    program = zigzag(400)
    fast = dataclasses.replace(program.segments[300], feed_m_s=1.0)
    program = Program(program.name, program.axis_names, program.segments[:300] + (fast,) + program.segments[301:])
    reference = live(program, "process", clamp_feed=False)
    with pytest.raises(ProgramError, match="feed_mm_min must be <="):
        for _ in run(reference):
            pass
    assert isinstance(reference.planner, plan_process.ProcessPlanner) and reference.planner.received_chunks > 0


def test_a_killed_child_is_a_fault_that_names_it() -> None:
    reference = live(zigzag(400), "process")
    planner = reference.planner
    assert isinstance(planner, plan_process.ProcessPlanner) and planner.remote.pid is not None
    os.kill(planner.remote.pid, signal.SIGKILL)  # our own child, by its id
    with pytest.raises(FaultError, match=rf"planner process \(pid {planner.remote.pid}\) ended"):
        for _ in run(reference):
            pass


def test_a_child_that_cannot_start_leaves_the_planning_here_and_says_why(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(plan_process, "CHILD_COMMAND", ("false",))
    program = zigzag(120)
    reference = live(program, "process", wait_ready=False)
    planner = reference.planner
    assert isinstance(planner, plan_process.ProcessPlanner)
    planner._feeder.join(WAIT_FLOOR_S)
    expected = [s.position_m for s in run(live(program, "thread"))]
    np.testing.assert_allclose(np.array([s.position_m for s in run(reference)]), np.array(expected), atol=1e-12)
    assert planner.received_chunks == 0
    assert planner.status_values()["plan_process"].startswith("not used: FaultError: the planner process")


points = st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3)


@st.composite
def segments(draw: st.DrawFn) -> list[Any]:
    """Lines and arcs (helices in any plane) of three axes, with and without source lines."""
    out: list[Any] = []
    for _ in range(draw(st.integers(1, 12))):
        start, feed, line = np.array(draw(points)), draw(st.floats(1e-3, 1.0)), draw(st.none() | st.integers(1, 9))
        if draw(st.booleans()):
            end = start + np.array(draw(points)) + 1e-3
            out.append(LineSegment(start, end, feed, line))
        else:
            plane = draw(st.sampled_from([(0, 1), (0, 2), (1, 2)]))
            angle, radius = draw(st.floats(0.0, 2 * math.pi)), draw(st.floats(1e-3, 0.2))
            center = start.copy()
            center[list(plane)] -= radius * np.array([math.cos(angle), math.sin(angle)])
            end = start.copy()
            end[3 - sum(plane)] += draw(st.floats(-0.01, 0.01))
            out.append(ArcSegment(start, end, center, draw(st.booleans()), plane, feed, line))
    return out


@settings(max_examples=50, deadline=None)
@given(segments())
def test_segments_cross_bit_for_bit(original: list[Any]) -> None:
    decoded = decode_segments(pickle.loads(pickle.dumps(encode_segments(original))))
    assert [type(s) for s in decoded] == [type(s) for s in original]
    for a, b in zip(decoded, original):
        assert a.__dict__.keys() == b.__dict__.keys()
        for name, value in b.__dict__.items():
            other = a.__dict__[name]
            if isinstance(value, np.ndarray):
                assert np.array_equal(other, value) and not other.flags.writeable, name
            else:
                assert other == value and type(other) is type(value), name
        assert np.array_equal(a.point(a.length_m / 3), b.point(b.length_m / 3))


#: Lines and arcs in xy from the blend properties' generator, 40-80 of them with random feeds.
contours = sibling_module(__file__, "test_blend_properties").arc_chains(40, 80, st.floats(0.01, 0.033))


@settings(max_examples=4, deadline=None)
@given(contours)
def test_on_generated_contours_the_child_plans_what_the_thread_plans(program: Program) -> None:
    """With a lead of 0.1 s the thread here plans little before the child is ready (a short program's whole plan
    within the 2 s lead would end the child before it was used)."""
    with mock.patch.object(plan_background, "FIR_LEAD_S", 0.1):
        by_process, by_thread = live(program, "process"), live(program, "thread")
    process_samples = np.array([s.position_m for s in run(by_process)])
    thread_samples = np.array([s.position_m for s in run(by_thread)])
    assert process_samples.shape == thread_samples.shape
    np.testing.assert_allclose(process_samples, thread_samples, rtol=0.0, atol=1e-12)
    assert isinstance(by_process.planner, plan_process.ProcessPlanner) and by_process.planner.received_chunks > 0
