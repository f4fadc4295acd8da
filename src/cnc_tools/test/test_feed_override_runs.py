"""The live feed override in the engine: a schedule with a feed hold keeps the limits, stays on the path, finishes.

Tier 1 (no DDS): the engine's interpolator stage steps
:class:`~cnc_contour_control.motion.feed_override.LiveReference`, the core object the
interpolator node steps; the graph test (tests/e2e/test_feed_override_graph.py)
compares the two.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.feed_override import OverrideConfig, OverrideInbox, check_source
from cnc_tools.analysis.scoring import score_run
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.engine_stages import SampledInterpolatorStage, VectorisedInterpolatorStage, interpolator_stage
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[3]
FEED_HOLD = ROOT / "scenarios" / "feed_hold_circle.yaml"
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
#: The schedule of the scenario: 1.0, 0.5 from 0.8 s, hold from 1.6 s, 1.0 from 2.4 s.
HOLD_S, RESUME_S = 1.6, 2.4


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    return load_scenario(FEED_HOLD)


@pytest.fixture(scope="module")
def record(scenario: Scenario) -> RunRecord:
    return run_engine(scenario)


def applied(record: RunRecord) -> np.ndarray:
    """The applied ratios of the record's reference series."""
    assert record.reference is not None and record.reference.feed_override_ratio is not None
    return record.reference.feed_override_ratio


def assert_within_axis_limits(record: RunRecord, scenario: Scenario) -> None:
    """Differentiate the recorded reference positions: velocity and acceleration within every axis's limits."""
    assert record.reference is not None
    t_s = scenario.sample_time_s
    position = record.reference.position_m
    v_max = np.asarray(scenario.limits.max_velocity_m_s) * (1 + 1e-9)
    a_max = np.asarray(scenario.limits.max_acceleration_m_s2) * (1 + 1e-9)
    assert np.all(np.abs(np.diff(position, axis=0) / t_s) <= v_max)
    assert np.all(np.abs(np.diff(position, 2, axis=0) / t_s**2) <= a_max)
    assert np.all(np.abs(record.reference.velocity_m_s) <= v_max)
    assert np.all(np.abs(record.reference.acceleration_m_s2) <= a_max)


def test_the_schedule_ramps_within_the_limits_on_the_path(record: RunRecord, scenario: Scenario) -> None:
    assert_within_axis_limits(record, scenario)
    assert record.reference is not None
    distance_m, _ = scenario.program.contour_distance(record.reference.position_m)
    assert distance_m.max() <= 1e-9


def test_the_applied_ratio_follows_the_requests_without_jumps(record: RunRecord) -> None:
    assert record.reference is not None and record.reference.feed_override_ratio is not None
    ratio, t_s = record.reference.feed_override_ratio, record.reference.stamp_ns * 1e-9
    assert ratio[t_s < 0.8].max() == 1.0
    assert ratio[(t_s > 1.3) & (t_s < HOLD_S)] == pytest.approx(0.5)
    assert np.all(ratio[(t_s > 2.0) & (t_s < RESUME_S)] == 0.0)
    assert 0.0 < ratio[np.searchsorted(t_s, HOLD_S)] < 0.5        # ramped down, not stepped
    assert np.all(ratio >= 0.0) and np.all(ratio <= 1.0)


def test_the_feed_hold_stops_on_the_path_and_the_run_resumes_and_finishes(record: RunRecord,
                                                                          scenario: Scenario) -> None:
    assert record.reference is not None
    ref, t_s = record.reference, record.reference.stamp_ns * 1e-9
    held = ref.feed_override_ratio == 0.0  # type: ignore[comparison-overlap]  # an array, compared elementwise
    assert held.sum() * scenario.sample_time_s > 0.5                # most of the 0.8 s hold
    assert np.ptp(ref.position_m[held], axis=0).max() == 0.0         # standing still
    assert np.all(ref.feed_m_s[held] == 0.0) and not ref.done[held].any()
    assert ref.path_length_m[t_s > RESUME_S + 0.5].min() > ref.path_length_m[held].max()  # resumed
    assert ref.done[-1] and ref.path_length_m[-1] == pytest.approx(scenario.program.total_length_m, abs=1e-12)


def test_the_run_is_scored_normally(record: RunRecord) -> None:
    score = score_run(record)
    assert score.contour.n_samples > 0
    assert all(math.isfinite(v) for v in score.contour.values_si.values())


def test_the_applied_ratio_round_trips_through_the_bag(record: RunRecord, tmp_path: Path) -> None:
    from cnc_tools.bagio.bag import read_bag
    from cnc_tools.bagio.record_bag import write_record_bag

    back = read_bag(write_record_bag(record, tmp_path / "bag"))
    assert np.array_equal(applied(back), applied(record))


def test_the_vectorised_interpolator_runs_only_where_no_override_can_occur(scenario: Scenario) -> None:
    stamps = np.arange(3, dtype=np.int64) * 10_000_000
    plain = load_scenario(CIRCLE, {"duration_s": 0.1})
    assert isinstance(interpolator_stage(plain, plain.pipeline(), stamps), VectorisedInterpolatorStage)
    assert isinstance(interpolator_stage(scenario, scenario.pipeline(), stamps), SampledInterpolatorStage)
    topic_only = plain.variant(feed_override={"max_ratio": 1.5})
    assert isinstance(interpolator_stage(topic_only, topic_only.pipeline(), stamps), SampledInterpolatorStage)
    record = run_engine(plain)
    assert record.reference is not None and np.all(record.reference.feed_override_ratio == 1.0)


def test_a_ratio_above_one_is_planned_for_and_keeps_the_limits() -> None:
    fast = load_scenario(FEED_HOLD, {"feed_override": {"max_ratio": 1.5, "schedule": [[0.0, 1.5], [1.0, 0.3],
                                                                                     [1.5, 1.5]]}})
    record = run_engine(fast)
    assert_within_axis_limits(record, fast)
    assert applied(record).max() == pytest.approx(1.5)


def test_the_accel_decel_filter_applies_to_the_overridden_reference() -> None:
    smooth = load_scenario(FEED_HOLD, {"interpolator": {"accel_decel": {"kind": "linear", "time_constant_s": 0.05}}})
    record, sharp = run_engine(smooth), run_engine(load_scenario(FEED_HOLD))
    assert_within_axis_limits(record, smooth)
    assert record.reference is not None and sharp.reference is not None
    assert np.array_equal(applied(record), applied(sharp))
    # a 5-tick moving average of the same samples (the filter starts at rest at the first one)
    p = sharp.reference.position_m
    padded = np.vstack([np.repeat(p[:1], 4, axis=0), p])
    expected = np.stack([padded[k:k + 5].mean(axis=0) for k in range(len(p))])
    assert np.allclose(record.reference.position_m, expected, rtol=0, atol=1e-15)


def test_the_runner_gives_the_interpolator_the_override_parameters(scenario: Scenario, tmp_path: Path) -> None:
    specs = {s.name: s.parameters for s in graph_specs(scenario, tmp_path)}
    interpolator: dict[str, Any] = dict(specs["interpolator"])
    assert interpolator["feed_override_source"] == "schedule"
    assert interpolator["feed_override"]["schedule_times_s"] == [0.0, 0.8, 1.6, 2.4]
    assert interpolator["feed_override"]["schedule_ratios"] == [1.0, 0.5, 0.0, 1.0]
    plain = {s.name: s.parameters for s in graph_specs(load_scenario(CIRCLE), tmp_path)}
    assert plain["interpolator"]["feed_override_source"] == "none" and "feed_override" not in plain["interpolator"]


@pytest.mark.parametrize(("schedule", "message"), [
    ([[0.0, 1.0], [0.5, 0.5], [0.5, 1.0]], r"schedule_times_s must increase, got 0.5 after 0.5 at entry 2"),
    ([[0.0, 1.2]], r"schedule_ratios\[0\] must be in \[0, max_ratio = 1.0\], got 1.2"),
    ([[0.0, -0.1]], r"schedule_ratios\[0\] must be in \[0, max_ratio = 1.0\], got -0.1"),
    ([[0.0, float("nan")]], r"schedule_ratios\[0\] must be a finite number|schedule_ratios\[0\].*nan"),
    ([[float("inf"), 1.0]], r"schedule_times_s\[0\]"),
    ([[-1.0, 1.0]], r"schedule_times_s\[0\] must be >= 0"),
    ([[0.0, 1.0, 2.0]], r"schedule must be a list of \[t_s, ratio\] pairs"),
])
def test_a_bad_schedule_is_refused_naming_the_entry(schedule: list[list[float]], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        load_scenario(FEED_HOLD, {"feed_override": {"schedule": schedule}})


def test_unknown_override_keys_and_ranges_are_refused() -> None:
    with pytest.raises(ConfigError, match=r"scenario.feed_override.ratio: unknown key"):
        load_scenario(FEED_HOLD, {"feed_override": {"ratio": 1.0}})
    with pytest.raises(ConfigError, match=r"max_ratio must be in \[0.0, 2.0\], got 3"):
        load_scenario(FEED_HOLD, {"feed_override": {"max_ratio": 3, "schedule": []}})


def test_the_source_must_agree_with_the_schedule() -> None:
    with_schedule = OverrideConfig(schedule_times_s=(0.0,), schedule_ratios=(0.5,))
    assert check_source("schedule", with_schedule) == "schedule"
    with pytest.raises(ConfigError, match="feed_override_source 'topic' and feed_override.schedule_times_s"):
        check_source("topic", with_schedule)
    with pytest.raises(ConfigError, match="feed_override_source must be one of"):
        check_source("knob", OverrideConfig())


def test_the_inbox_takes_the_previous_ticks_message_exactly() -> None:
    inbox = OverrideInbox(previous_tick=True)
    assert inbox.ready() and inbox.take(0) == 1.0                   # tick 0: nothing before it
    assert not inbox.ready()                                          # tick 1 waits for feed_override(0)
    assert inbox.add(10, 0.7) is None and not inbox.ready()          # tick 1's own message does not count
    assert inbox.add(0, 0.4) is None and inbox.ready() and inbox.take(10) == 0.4
    assert inbox.ready() and inbox.take(20) == 0.7


def test_the_inbox_refuses_a_bad_ratio_and_holds_the_last_valid_one() -> None:
    inbox = OverrideInbox(previous_tick=False)
    assert inbox.take(0) == 1.0
    assert inbox.add(0, 0.6) is None and inbox.take(10) == 0.6
    assert "must be finite and in [0, max_ratio = inf], got -0.5; holding 0.6" in (inbox.add(10, -0.5) or "")
    assert "got nan" in (inbox.add(20, float("nan")) or "") and inbox.take(30) == 0.6
