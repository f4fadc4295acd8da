"""The FIR jerk filter on its own clock (``LiveReference``): ticks whose period varies, as in a real-time graph under
load, read the reference the filter makes every ``jerk_filter_period_s``.

Checked on generated tick sequences: a tick on the filter's clock gets exactly the sample that regular 1 ms ticks
get; a tick between two of its steps lies on the straight line between those two samples; a repeated stamp answers
the same sample; the run ends at the program's end point, at rest and ``done``.
"""
from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig
from cnc_contour_control.motion.geometry import LineSegment, Program
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.reference_types import ReferenceSample

MS_NS = 1_000_000
LIMITS = AxisLimits((2000 / 60000,) * 2, (0.25, 0.25), (10.0, 10.0))
CONFIG = InterpolatorConfig(path_tolerance_mm=0.01, jerk_mode="fir")
#: An L of two 3 mm lines at 1200 mm/min: about 0.4 s of motion, the filter's window 50 ms.
PROGRAM = Program("L", ("x", "y"), (LineSegment(np.array([0.0, 0.0]), np.array([0.003, 0.0]), 0.02),
                                     LineSegment(np.array([0.003, 0.0]), np.array([0.003, 0.003]), 0.02)))
SETTINGS = settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _regular(until_ns: int) -> dict[int, ReferenceSample]:
    """The reference at every 1 ms tick up to ``until_ns``."""
    live = LiveReference(PROGRAM, LIMITS, CONFIG, OverrideConfig())
    return {t: live.step(t, 1.0) for t in range(0, until_ns + MS_NS, MS_NS)}


REGULAR = _regular(700 * MS_NS)


@SETTINGS
@given(st.lists(st.integers(1, 40 * MS_NS), min_size=150, max_size=400))
def test_ticks_of_any_period_read_the_filters_own_samples(gaps_ns: list[int]) -> None:
    live = LiveReference(PROGRAM, LIMITS, CONFIG, OverrideConfig())
    stamp_ns, sample = 0, live.step(0, 1.0)
    for gap_ns in gaps_ns:
        stamp_ns += gap_ns
        if stamp_ns > 700 * MS_NS:
            break
        sample = live.step(stamp_ns, 1.0)
        assert np.array_equal(live.step(stamp_ns, 1.0).position_m, sample.position_m)  # a repeat: the same
        below, share = divmod(stamp_ns, MS_NS)
        if share == 0:
            assert np.array_equal(sample.position_m, REGULAR[stamp_ns].position_m)
            continue
        before, after = REGULAR[below * MS_NS], REGULAR[(below + 1) * MS_NS]
        expected = before.position_m + share / MS_NS * (after.position_m - before.position_m)
        assert np.allclose(sample.position_m, expected, rtol=0.0, atol=1e-15)
        expected_v = before.velocity_m_s + share / MS_NS * (after.velocity_m_s - before.velocity_m_s)
        assert np.allclose(sample.velocity_m_s, expected_v, rtol=0.0, atol=1e-15)


def test_a_run_of_late_ticks_ends_at_the_end_point_at_rest_and_done() -> None:
    live = LiveReference(PROGRAM, LIMITS, CONFIG, OverrideConfig())
    samples = [live.step(t, 1.0) for t in range(0, 2000 * MS_NS, 7 * MS_NS + 300_000)]
    done = [s.done for s in samples]
    assert True in done, "the run never ended"
    last = samples[done.index(True)]
    assert np.allclose(last.position_m, [0.003, 0.003], rtol=0.0, atol=1e-15)
    assert np.abs(last.velocity_m_s).max() < 1e-12
    assert all(done[done.index(True):])
