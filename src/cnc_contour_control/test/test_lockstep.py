"""Lockstep bookkeeping: matching by stamp, stale inputs, timeouts that name what is missing."""
from __future__ import annotations

import math

import pytest

from cnc_contour_control.core.errors import ConfigError, FaultError, InputFault
from cnc_contour_control.core.lockstep import (
    StampMatcher,
    duration_to_ns,
    join_ns,
    ns_to_s,
    require_finite_values,
    require_same_axes,
    seconds_to_ns,
    split_ns,
    stamp_horizon_ns,
)


def test_a_tick_is_released_once_all_inputs_hold_its_stamp_in_any_order() -> None:
    matcher = StampMatcher(("joint_states", "reference"), timeout_s=1.0)
    assert matcher.add("reference", 10, "r0", now_s=0.0) is None
    assert matcher.add("reference", 20, "r1", now_s=0.0) is None
    assert matcher.add("joint_states", 10, "j0", now_s=0.0) == {"reference": "r0", "joint_states": "j0"}
    assert matcher.add("joint_states", 20, "j1", now_s=0.0) == {"reference": "r1", "joint_states": "j1"}
    assert matcher.pending_count == 0


def test_late_duplicates_of_released_ticks_are_ignored() -> None:
    matcher = StampMatcher(("a", "b"), timeout_s=1.0)
    matcher.add("a", 10, 1, 0.0)
    matcher.add("b", 10, 2, 0.0)
    assert matcher.add("a", 10, 3, 0.0) is None and matcher.add("b", 5, 4, 0.0) is None
    assert matcher.pending_count == 0


def test_overdue_names_the_missing_inputs_of_the_oldest_tick() -> None:
    matcher = StampMatcher(("joint_states", "reference", "compensation"), timeout_s=1.0)
    matcher.add("joint_states", 10, None, now_s=0.0)
    matcher.add("reference", 10, None, now_s=0.5)
    assert matcher.overdue(now_s=1.0) is None
    assert matcher.overdue(now_s=1.01) == (10, ["compensation"])


def test_the_first_tick_gets_the_startup_timeout_later_ticks_the_short_one() -> None:
    matcher = StampMatcher(("a", "b"), timeout_s=1.0, startup_timeout_s=30.0)
    matcher.expect(0, now_s=0.0)
    assert matcher.overdue(now_s=29.0) is None and matcher.current_timeout_s == 30.0
    assert matcher.overdue(now_s=30.5) == (0, ["a", "b"])
    matcher.add("a", 0, None, 30.6)
    matcher.add("b", 0, None, 30.6)
    matcher.expect(10, now_s=31.0)
    assert matcher.current_timeout_s == 1.0 and matcher.overdue(now_s=32.1) == (10, ["a", "b"])


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"required": (), "timeout_s": 1.0}, ["at least one"]),
    ({"required": ("a",), "timeout_s": 0.0}, ["timeout_s", "> 0", "0.0"]),
    ({"required": ("a",), "timeout_s": 2.0, "startup_timeout_s": 1.0}, ["startup_timeout_s", ">= timeout_s", "1.0"]),
])
def test_bad_matcher_settings_are_refused(kwargs: dict, words: list[str]) -> None:
    with pytest.raises(ConfigError) as caught:
        StampMatcher(**kwargs)
    assert all(word in str(caught.value) for word in words)


def test_an_unknown_input_is_a_fault_naming_it() -> None:
    with pytest.raises(FaultError, match="'cutting_force'.*'a'"):
        StampMatcher(("a",), 1.0).add("cutting_force", 0, None, 0.0)


def test_time_conversions_are_exact_in_integer_nanoseconds() -> None:
    assert seconds_to_ns(0.001) == 1_000_000 and seconds_to_ns(0.01) == 10_000_000
    assert ns_to_s(7 * 1_000_000) == 0.007
    assert duration_to_ns(6.4731966938) == 6_473_196_694
    with pytest.raises(ConfigError, match="whole number of nanoseconds"):
        seconds_to_ns(1e-10)
    with pytest.raises(ConfigError, match="duration_s must be > 0"):
        duration_to_ns(-1.0)


@pytest.mark.parametrize("stamp_ns", [0, 999_999_999, 1_000_000_000, 6_473_196_694, 2**62])
def test_stamps_split_into_time_fields_and_join_back(stamp_ns: int) -> None:
    sec, nanosec = split_ns(stamp_ns)
    assert 0 <= nanosec < 1_000_000_000 and join_ns(sec, nanosec) == stamp_ns


def test_non_finite_values_and_wrong_axes_are_faults_naming_the_field() -> None:
    require_finite_values([0.0, 1.0], "x")
    with pytest.raises(FaultError, match=r"joint_states.position\[1\]: nan"):
        require_finite_values([0.0, math.nan], "joint_states.position")
    with pytest.raises(FaultError, match=r"\['x', 'z'\], expected \['x', 'y'\]"):
        require_same_axes(["x", "z"], ["x", "y"], "joint_states")


# --------------------------------------------------------------------------- messages from outside the run
T_NS = 10_000_000


def _released(matcher: StampMatcher, stamp_ns: int) -> None:
    for name in matcher.required:
        matcher.add(name, stamp_ns, name, 0.0)
    assert matcher.last_released_ns == stamp_ns


def test_a_stamp_beyond_the_horizon_is_a_fault_naming_the_input() -> None:
    matcher = StampMatcher(("joint_states", "reference"), 1.0, max_ahead_ns=stamp_horizon_ns(T_NS))
    _released(matcher, 0)
    assert matcher.add("reference", T_NS, None, 0.0) is None, "the next tick is fine"
    with pytest.raises(FaultError, match=r"joint_states stamped t=1000\.000000 s, more than 1\.0 s after tick t=0\.0"):
        matcher.add("joint_states", 1000 * 1_000_000_000, None, 0.0)


def test_a_far_future_input_held_before_the_first_tick_is_a_fault_once_the_first_tick_is_released() -> None:
    matcher = StampMatcher(("joint_states", "reference"), 1.0, max_ahead_ns=stamp_horizon_ns(T_NS))
    assert matcher.add("joint_states", 1000 * 1_000_000_000, None, 0.0) is None  # nothing to compare with yet
    matcher.add("joint_states", 0, None, 0.0)
    with pytest.raises(InputFault, match="joint_states stamped t=1000.000000 s") as raised:
        matcher.add("reference", 0, None, 0.0)
    assert raised.value.input_name == "joint_states", "the input at fault, not the one whose arrival found it"


def test_a_stage_lagging_behind_one_input_in_real_time_is_no_fault() -> None:
    # Real time: the plant does not wait, so joint_states runs ahead while the references lag by over 1 s.
    matcher = StampMatcher(("joint_states", "reference"), 1.0, max_ahead_ns=stamp_horizon_ns(T_NS))
    for k in range(150):  # held before the first tick (checked on its release), then after it
        assert matcher.add("joint_states", k * T_NS, None, 0.0) is None
        if k == 60:
            assert matcher.add("reference", 0, "r", 0.0) == {"joint_states": None, "reference": "r"}
    for k in range(1, 150):
        assert matcher.add("reference", k * T_NS, "r", 0.0) == {"joint_states": None, "reference": "r"}
    matcher.add("joint_states", 240 * T_NS, None, 0.0)  # a gap within the horizon of its own stream
    with pytest.raises(FaultError, match=r"joint_states stamped t=1000\.000000 s, more than 1\.0 s after tick t=2\.4"):
        matcher.add("joint_states", 1000 * 1_000_000_000, None, 0.0)


def test_a_second_message_for_a_pending_tick_is_a_fault() -> None:
    matcher = StampMatcher(("joint_states", "reference"), 1.0)
    matcher.add("joint_states", T_NS, None, 0.0)
    with pytest.raises(FaultError, match=r"joint_states: a second message for tick t=0\.010000 s"):
        matcher.add("joint_states", T_NS, None, 0.0)


def test_a_pending_tick_passed_by_a_later_complete_one_is_a_fault() -> None:
    matcher = StampMatcher(("joint_states", "reference"), 1.0)
    matcher.add("reference", 5_000_000, None, 0.0)  # between two ticks: not of this run
    matcher.add("joint_states", T_NS, None, 0.0)
    with pytest.raises(FaultError, match=r"reference stamped t=0\.005000 s never completed a tick and was passed"):
        matcher.add("reference", T_NS, None, 0.0)


def test_a_plant_accepts_only_the_tick_it_published_and_forgets_an_expected_tick_that_never_came() -> None:
    matcher = StampMatcher(("x", "y"), 1.0, max_ahead_ns=0)
    matcher.expect(0, 0.0)
    with pytest.raises(FaultError, match=r"x stamped t=0\.010000 s, more than 0\.0 s after tick t=0\.0"):
        matcher.add("x", T_NS, None, 0.0)
    waiting = StampMatcher(("joint_states",), 1.0, max_ahead_ns=stamp_horizon_ns())
    waiting.expect(0, 0.0)
    assert waiting.add("joint_states", 3 * T_NS, "j", 0.0) == {"joint_states": "j"}  # a run starting later
    assert waiting.pending_count == 0


def test_a_held_future_input_does_not_time_out_before_its_tick_is_next() -> None:
    matcher = StampMatcher(("joint_states", "reference"), timeout_s=1.0)
    matcher.add("joint_states", 2 * T_NS, None, now_s=0.0)  # early, e.g. a fast producer
    matcher.add("joint_states", T_NS, None, now_s=5.0)
    matcher.add("reference", T_NS, None, now_s=5.0)
    assert matcher.overdue(now_s=5.9) is None, "the clock of tick 2 starts when tick 1 is released"
    assert matcher.overdue(now_s=6.1) == (2 * T_NS, ["reference"])


def test_the_stamp_horizon_is_ten_ticks_and_at_least_a_second() -> None:
    assert stamp_horizon_ns(T_NS) == 1_000_000_000
    assert stamp_horizon_ns(500_000_000) == 5_000_000_000
    assert stamp_horizon_ns() == 10_000_000_000, "a stage without T takes the largest T the nodes accept"
    with pytest.raises(ConfigError, match="max_ahead_ns must be >= 0, got -1"):
        StampMatcher(("a",), 1.0, max_ahead_ns=-1)
