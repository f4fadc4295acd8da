"""Paper 004's bench, our law for the 4-bit switch: no limit cycle, overshoot at the sampled loop's floor (tier 1)."""
from __future__ import annotations

import pytest

from cnc_tools.reproductions.paper004 import data
from cnc_tools.reproductions.paper004.bench import MAX_CHANGES_PER_S, STEP_PHASES_S, floors
from cnc_tools.reproductions.paper004.runs import (
    OURS_CASES,
    OURS_NO_JUMP,
    UPDATE_PERIOD_S,
    Result,
    run_case,
    step_phase_overshoots,
)

BAND_N = data.BAND_FRACTION * data.REFERENCE_N


@pytest.fixture(scope="module")
def ours() -> Result:
    return run_case(next(c for c in OURS_CASES if c.key == "ours/4bit"))


def test_where_a_level_lands_it_holds_and_where_none_does_the_mean_holds_with_few_changes(ours: Result) -> None:
    at_1, at_2, at_3 = ours.segments
    assert at_1.switchings_per_s == 0.0 and at_2.switchings_per_s == 0.0
    assert at_3.switchings_per_s <= MAX_CHANGES_PER_S
    assert all(abs(s.mean_n - data.REFERENCE_N) <= BAND_N for s in ours.segments)


def test_both_steps_overshoot_at_most_1_2_times_the_floor(ours: Result) -> None:
    at_once = floors()
    step_12, step_23 = ours.segments[1], ours.segments[2]
    assert step_12.step_overshoot_pct <= 1.2 * at_once[(1.0, 2.0)].overshoot_pct
    assert step_23.step_overshoot_pct <= 1.2 * at_once[(2.0, 3.0)].overshoot_pct


def test_the_2_to_3_mm_step_is_cut_at_the_first_update_that_sees_it_whatever_its_phase() -> None:
    """Wherever the step falls in the 10 ms update period, the overshoot is at most that of a cut 10 ms late."""
    late = floors(UPDATE_PERIOD_S)[(2.0, 3.0)].overshoot_pct
    ours = next(c for c in OURS_CASES if c.key == "ours/4bit")
    overshoots = step_phase_overshoots(ours, (2.0, 3.0), STEP_PHASES_S)
    assert max(overshoots) <= late, overshoots
    assert late > 1.2 * floors()[(2.0, 3.0)].overshoot_pct, "a cut 10 ms late is above the goal from 500 N"
    without = step_phase_overshoots(OURS_NO_JUMP, (2.0, 3.0), STEP_PHASES_S)
    assert max(without) > late, f"the surface alone misses an update's first milliseconds: {without}"


def test_with_the_preview_both_steps_stay_within_5_percent() -> None:
    result = run_case(next(c for c in OURS_CASES if c.key == "preview-ours/4bit"))
    assert all(s.step_overshoot_pct <= 5.0 for s in result.segments[1:])
