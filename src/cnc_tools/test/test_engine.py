"""The engine steps the stage pipeline and gives the same run record a bag gives (tier 1, no DDS)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.axis.servo import ServoController
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.stages import STAGES, pipeline
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.engine import ENGINE_STAGES, build_stages, run_engine, tick_count
from cnc_tools.runs.engine_stages import SampledInterpolatorStage, VectorisedInterpolatorStage
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
HELIX = ROOT / "scenarios" / "helix_3axis.yaml"


@pytest.fixture(scope="module")
def circle() -> RunRecord:
    return run_engine(load_scenario(CIRCLE, {"duration_s": 1.5}))


def test_engine_record_has_every_per_tick_series(circle: RunRecord) -> None:
    n = circle.ticks
    assert circle.backend == "engine" and circle.integrity.complete
    assert circle.reference is not None and circle.reference.stamp_ns.size == n
    assert set(circle.commands) == {"x", "y"}
    for series in circle.commands.values():
        assert series.stamp_ns.size == n
        for part in (series.command, series.feedback, series.feedforward, series.error_m):
            assert np.isfinite(part).all(), "every command part is recorded, none NaN"
    assert circle.summary["ticks"] == n and circle.summary["faults"] == []
    assert circle.summary["plant"]["model"] == "paper000"


def test_engine_command_parts_are_what_the_servo_computes(circle: RunRecord) -> None:
    scenario = load_scenario(CIRCLE, {"duration_s": 1.5})
    assert circle.reference is not None
    for k, config in enumerate(scenario.servos):
        servo, series = ServoController(config), circle.commands[config.axis_name]
        dt_s = scenario.sample_time_s
        for i in range(circle.ticks):
            out = servo.step(dt_s, float(circle.reference.position_m[i, k]), float(circle.reference.velocity_m_s[i, k]),
                             float(circle.reference.acceleration_m_s2[i, k]),
                             float(circle.joint_states.position_m[i, k]),
                             float(circle.joint_states.velocity_m_s[i, k]), 0.0)
            assert (out.command, out.feedback, out.feedforward) == (
                series.command[i], series.feedback[i], series.feedforward[i])


def test_per_tick_reference_equals_the_vectorised_one() -> None:
    scenario = load_scenario(HELIX, {"duration_s": 2.0})
    stamps = np.arange(tick_count(scenario), dtype=np.int64) * 10_000_000
    fast = VectorisedInterpolatorStage(scenario, scenario.pipeline(), stamps)
    slow = SampledInterpolatorStage(scenario, scenario.pipeline(), stamps)
    from cnc_tools.runs.engine_stages import Board

    board = Board(0.01)
    for k, stamp in enumerate(stamps.tolist()):
        board.tick, board.stamp_ns = k, stamp
        fast.step(board)
        slow.step(board)
    a, b = fast.series()["reference"], slow.series()["reference"]
    for name in ("position_m", "velocity_m_s", "acceleration_m_s2", "path_length_m", "feed_m_s"):
        assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-12, err_msg=name)
    assert (a.segment_index == b.segment_index).all() and (a.done == b.done).all()


def test_every_core_stage_has_an_engine_implementation() -> None:
    core = [s.name for s in STAGES.values() if not s.optional]
    assert set(core) <= set(ENGINE_STAGES)


def test_a_stage_without_engine_implementation_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(ENGINE_STAGES, "force_regulator")  # every stage has one now: take one away
    scenario = load_scenario(CIRCLE, {"duration_s": 0.1})
    with pytest.raises(ConfigError, match="'force_regulator' has no engine implementation"):
        build_stages(scenario, pipeline(scenario.axes, ["force_regulator"]), np.zeros(3, np.int64))


def test_engine_run_folder_is_like_a_graph_runs(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE, {"duration_s": 0.5})
    record = run_scenario(scenario, "engine", tmp_path / "run")
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["ticks"] == record.ticks == tick_count(scenario)
    assert (tmp_path / "run" / "scenario.yaml").is_file()
    assert record.source == tmp_path / "run"
    from cnc_tools.bagio.bag import read_bag

    assert read_bag(tmp_path / "run" / "bag").ticks == record.ticks


def test_unknown_backend_lists_the_valid_ones() -> None:
    with pytest.raises(ConfigError, match=r"backend must be one of \['engine', 'graph'\]"):
        run_scenario(load_scenario(CIRCLE, {"duration_s": 0.1}), "cloud")


def test_variant_revalidates_and_keeps_the_program_folder() -> None:
    base = load_scenario(ROOT / "scenarios" / "paper000_line_low.yaml")
    other = base.variant({"plant": {"variation": {"gain_pct": 1.0}}}, seed=base.seed + 7)
    assert other.seed == base.seed + 7 and other.plant.variation.gain_pct == 1.0
    assert other.program.total_length_m == base.program.total_length_m and other.source == base.source
    with pytest.raises(ConfigError, match="sample_time_s must be > 0"):
        base.variant(sample_time_s=-1.0)


def test_engine_record_written_as_a_bag_reads_back_equal(circle: RunRecord, tmp_path: Path) -> None:
    from cnc_tools.bagio.bag import read_bag
    from cnc_tools.bagio.record_bag import write_record_bag

    back = read_bag(write_record_bag(circle, tmp_path / "bag"))
    assert back.integrity.complete and back.ticks == circle.ticks
    assert_allclose(back.joint_states.position_m, circle.joint_states.position_m, rtol=0, atol=0)
    assert back.reference is not None and circle.reference is not None
    for name in ("position_m", "velocity_m_s", "acceleration_m_s2", "path_length_m", "feed_m_s"):
        assert_allclose(getattr(back.reference, name), getattr(circle.reference, name), rtol=0, atol=0)
    for axis, series in circle.commands.items():
        for name in ("command", "feedback", "feedforward", "compensation", "disturbance_estimate", "error_m"):
            assert_allclose(getattr(back.commands[axis], name), getattr(series, name), rtol=0, atol=0)
        assert (back.commands[axis].saturated == series.saturated).all()
    assert back.program.total_length_m == circle.program.total_length_m


def test_optional_stage_series_go_to_their_topics_and_come_back(circle: RunRecord, tmp_path: Path) -> None:
    from cnc_tools.bagio.bag import read_bag
    from cnc_tools.bagio.record_bag import write_record_bag
    from cnc_tools.run_record import CompensationSeries, EstimateSeries, FeedOverrideSeries, ForceSeries

    n, stamps, rng = circle.ticks, circle.joint_states.stamp_ns, np.random.default_rng(3)
    full = circle.with_(
        contour_error=EstimateSeries(stamps, rng.normal(size=n), rng.normal(size=(n, 2)),
                                     rng.integers(0, 9, n).astype(np.int64), rng.normal(size=n),
                                     rng.normal(size=(n, 2)), rng.normal(size=(n, 2)),
                                     rng.integers(1, 9, n).astype(np.int64), rng.integers(0, 5, n).astype(np.int64),
                                     "window"),
        compensation=CompensationSeries(stamps, rng.normal(size=(n, 2)), "dac", rng.integers(0, 2, n).astype(bool),
                                        "neural"),
        feed_override=FeedOverrideSeries(stamps, rng.uniform(0, 1.5, n), rng.uniform(0, 1.5, n)),
        cutting_force=ForceSeries(stamps, rng.normal(size=(n, 3)), rng.normal(size=(n, 3))))
    back = read_bag(write_record_bag(full, tmp_path / "bag"))
    for name in ("contour_error", "compensation", "feed_override", "cutting_force"):
        got, sent = getattr(back, name), getattr(full, name)
        for field in ("stamp_ns", "contour_error_m", "tracking_error_m", "segment_index", "angle_rad", "point_a_m",
                      "point_b_m", "window_size", "window_steps", "correction", "learning", "requested_ratio",
                      "applied_ratio", "force_n", "torque_n_m"):
            if hasattr(sent, field):
                assert_allclose(getattr(got, field), getattr(sent, field), rtol=0, atol=0, err_msg=f"{name}.{field}")
    assert back.compensation is not None and back.compensation.command_unit == "dac"
    assert back.compensation.method == "neural"
    assert back.contour_error is not None and back.contour_error.method == "window"
    assert circle.contour_error is None and read_bag(write_record_bag(circle, tmp_path / "plain")).contour_error is None
