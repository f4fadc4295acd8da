"""Paper 004's bench, our law for the 4-bit switch: no limit cycle, overshoot at the sampled loop's floor (tier 1)."""
from __future__ import annotations

import pytest

from cnc_tools.reproductions.paper004 import data
from cnc_tools.reproductions.paper004.bench import MAX_CHANGES_PER_S, floors
from cnc_tools.reproductions.paper004.runs import OURS_CASES, UPDATE_PERIOD_S, Result, run_case

BAND_N = data.BAND_FRACTION * data.REFERENCE_N


@pytest.fixture(scope="module")
def ours() -> Result:
    return run_case(next(c for c in OURS_CASES if c.key == "ours/4bit"))


def test_where_a_level_lands_it_holds_and_where_none_does_the_mean_holds_with_few_changes(ours: Result) -> None:
    at_1, at_2, at_3 = ours.segments
    assert at_1.switchings_per_s == 0.0 and at_2.switchings_per_s == 0.0
    assert at_3.switchings_per_s <= MAX_CHANGES_PER_S
    assert all(abs(s.mean_n - data.REFERENCE_N) <= BAND_N for s in ours.segments)


def test_the_step_overshoot_is_at_the_floor_of_a_loop_that_updates_every_10_ms(ours: Result) -> None:
    at_once, one_update_late = floors(), floors(UPDATE_PERIOD_S)
    step_12, step_23 = ours.segments[1], ours.segments[2]
    assert step_12.step_overshoot_pct <= 1.2 * at_once[(1.0, 2.0)].overshoot_pct
    assert step_23.step_overshoot_pct <= one_update_late[(2.0, 3.0)].overshoot_pct
    assert one_update_late[(2.0, 3.0)].overshoot_pct > 1.2 * at_once[(2.0, 3.0)].overshoot_pct, (
        "no feedback law that sees the step at its next update reaches 1.2 x the floor of a cut at the step")


def test_with_the_preview_both_steps_stay_within_5_percent() -> None:
    result = run_case(next(c for c in OURS_CASES if c.key == "preview-ours/4bit"))
    assert all(s.step_overshoot_pct <= 5.0 for s in result.segments[1:])
