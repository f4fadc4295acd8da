"""Estimator fidelity on real closed-loop motion (engine, T = 1 ms) and the ``estimator`` bench (no timing
assertions)."""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.estimators import make_estimator
from cnc_contour_control.motion.geometry import ArcSegment
from cnc_contour_control.motion.program import load_program
from cnc_tools.analysis.scoring import contour_error_series
from cnc_tools.bench import estimator as estimator_bench_module
from cnc_tools.bench.registry import BENCHES
from cnc_tools.reproductions.paper001.fidelity import (
    CONTOURS,
    GOAL_MAX_UM,
    GOAL_RMS_UM,
    GOAL_STEPS,
    exact_of,
    following_mask,
    get_contour,
    involute_program,
    measure,
    run_contour,
    steady_mask,
    trace,
)
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def records() -> dict[str, object]:
    """Engine runs of the contours the tests look at (each well under a second)."""
    return {name: run_contour(get_contour(name), ROOT) for name in ("circle", "involute", "corner", "helix")}


def test_every_contour_scenario_loads_at_1_khz() -> None:
    for contour in CONTOURS:
        scenario = contour.load(ROOT)
        assert scenario.sample_time_s == 0.001, contour.name
    assert get_contour("helix").load(ROOT).axes == ("x", "y", "z")
    with pytest.raises(ConfigError,
                       match=r"contour must be one of \['circle', 'corner', 'helix', 'involute', 'line'\]"):
        get_contour("ellipse")


def test_the_involute_scenario_is_the_generators_program_and_tangent_continuous() -> None:
    scenario = get_contour("involute").load(ROOT)
    generated = load_program(involute_program(), name="involute")
    assert len(scenario.program.segments) == len(generated.segments) == 148
    for ours, theirs in zip(scenario.program.segments, generated.segments):
        assert isinstance(ours, ArcSegment) and not ours.clockwise
        assert_allclose(ours.end_m, theirs.end_m, atol=1e-12)
        assert_allclose(ours.center_m, theirs.center_m, atol=1e-12)
    interpolator = scenario.make_interpolator()
    assert np.all(interpolator.junction_speeds_m_s[1:-1] > 0.0)  # no exact stop at any junction
    step = (3 * math.pi - 2.0) / 148  # radius a·t at each arc's middle, a = 2 mm, t = 2 .. 3π
    radii = [s.radius_m for s in scenario.program.segments]
    assert_allclose(radii, 2e-3 * (2.0 + step * (np.arange(148) + 0.5)), rtol=1e-9)


def test_exact_error_is_the_scorers_distance_with_the_left_positive_sign(records: dict[str, object]) -> None:
    record = records["circle"]
    exact = exact_of(record)  # type: ignore[arg-type]  # the fixture's records are RunRecords
    series, _ = contour_error_series(record)  # type: ignore[arg-type]  # the fixture's records are RunRecords
    assert_allclose(np.abs(exact.error_m), series.error_m, rtol=0, atol=0)
    center = np.array([0.0, 0.01])  # ccw circle: inside is left of travel
    inside = np.linalg.norm(series.position_m - center, axis=1) < 0.01
    moved = np.abs(exact.error_m) > 1e-9
    assert np.all(exact.error_m[inside & moved] > 0) and np.all(exact.error_m[~inside & moved] < 0)


def test_following_mask_is_the_lag_behind_the_last_reference_step() -> None:
    reference = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 0.0], [2.0, 0.0]]) * 1e-3
    position = np.array([[0.0, 0.0], [0.0, 0.0], [0.5, 0.1], [2.2, 0.0], [1.9, 0.0], [2.1, -0.1]]) * 1e-3
    assert following_mask(reference, position).tolist() == [True, True, True, False, True, False]


def test_steady_state_is_a_constant_feed_held_for_the_window() -> None:
    feed = np.r_[np.linspace(0.0, 1.0, 50), np.ones(300), np.linspace(1.0, 0.0, 50)]
    steady = steady_mask(feed, np.ones(feed.size, dtype=bool), ticks=100)
    assert not steady[:149].any() and steady[149:351].all() and not steady[351:].any()  # 49..350 hold 1.0


@pytest.mark.parametrize("name", ["circle", "involute", "helix"])
def test_window_estimator_meets_the_goals_on_smooth_contours(records: dict[str, object], name: str) -> None:
    names = ["window"] if name == "helix" else ["window", "path"]
    rows = {row.estimator: row for row in measure(get_contour(name), records[name], names)}  # type: ignore[arg-type]  # the fixture's records are RunRecords
    window = rows["window"]
    assert window.contour_max_um > 100.0  # real contour errors, far above the estimator's
    assert window.max_um <= GOAL_MAX_UM and window.rms_um <= GOAL_RMS_UM, window
    assert window.steps_max <= GOAL_STEPS and window.steady_samples > 500 and window.goals_met
    if "path" in rows:
        assert rows["path"].max_um < 1e-6  # the scorer's own geometry, tracked per segment


def test_at_the_corner_the_window_errs_in_sign_at_the_vertex_only(records: dict[str, object]) -> None:
    row, = measure(get_contour("corner"), records["corner"], ["window"])  # type: ignore[arg-type]  # the fixture's records are RunRecords
    assert row.goals_met is None
    assert row.magnitude_max_um < 1e-3  # magnitudes agree while following the reference
    assert row.max_um > 10.0 and row.worst.junction_mm < 1e-3  # the signed worst case sits on the vertex
    assert row.ahead_samples > 0 and row.ahead.error_um > 10.0  # overshoot past the vertex and the end


def test_window_within_1_um_on_paper001s_circle_where_the_position_leads() -> None:
    record = run_engine(load_scenario(ROOT / "scenarios" / "paper001_circle.yaml"))
    exact = exact_of(record)
    moving = ~record.reference.done.astype(bool)  # type: ignore[union-attr]  # an engine run has references
    leading = ~exact.following & moving
    assert leading.sum() > 0.7 * moving.sum()  # the PID's loop leads its reference most of the time
    found = trace(make_estimator("window", {}, record.program), record.reference.position_m,  # type: ignore[union-attr]  # as above
                  record.joint_states.position_m)
    difference_um = np.abs(found.error_m - exact.error_m) / 1e-6
    assert np.max(np.abs(exact.error_m[leading])) > 50e-6  # real errors, far above the estimator's
    assert difference_um[leading].max() <= GOAL_MAX_UM and difference_um[exact.following].max() <= GOAL_MAX_UM


def test_bench_prints_both_tables_and_writes_json(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("CNC_CONTOUR_ROOT", str(ROOT))
    monkeypatch.setattr(estimator_bench_module, "CONTOURS", (get_contour("line"),))
    monkeypatch.setattr(estimator_bench_module, "COST_CONTOUR", "line")
    out = tmp_path / "estimator.json"
    assert BENCHES["estimator"](argparse.Namespace(name="estimator", quick=True, json=out)) == 0
    printed = capsys.readouterr().out
    assert "max|Δ| µm" in printed and "steps mean" in printed and "ratio to ServoController.parts" in printed
    figures = json.loads(out.read_text())
    assert {row["estimator"] for row in figures["rows"]} == {"path", "window"}
    assert set(figures["step_us"]) == {"path", "window", "servo"} and figures["ratio_to_servo"]["servo"] == 1.0
    assert all(us > 0 for us in figures["step_us"].values())
