"""Preview plans on a schedule of many close steps: one plan per window, never overlapping (tier 1)."""
from __future__ import annotations

from cnc_contour_control.force import DepthSchedule, QuantiserConfig, TurningModelConfig, plan_schedule

MODEL = TurningModelConfig(depth_min_mm=1.0, depth_max_mm=3.0)


def test_close_steps_share_a_window_and_the_windows_do_not_overlap() -> None:
    rows = tuple((0.02 * i, 1.0 + (i % 3)) for i in range(101))  # a step every 20 ms for 2 s
    schedule = DepthSchedule(rows)
    plans = plan_schedule(MODEL, schedule, 500.0, 0.01, QuantiserConfig())
    assert 2 <= len(plans) <= 4, "one linear program per 0.8 s window, not one per step (100)"
    assert all(a.end_s <= b.start_s + 1e-9 for a, b in zip(plans, plans[1:]))
    covered = [any(p.start_s - 1e-9 <= t < p.end_s for p in plans) for t in schedule.step_times_s()]
    assert all(covered[: len(covered) - 1]), "every step but possibly the last lies in some plan's window"


def test_steps_a_window_apart_keep_their_full_lead() -> None:
    schedule = DepthSchedule(((0.0, 1.0), (4.0, 2.0), (8.0, 3.0)))
    plans = plan_schedule(MODEL, schedule, 500.0, 0.01, QuantiserConfig())
    assert [round(p.start_s, 9) for p in plans] == [3.7, 7.7]
