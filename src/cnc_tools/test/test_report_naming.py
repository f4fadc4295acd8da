"""Runs and plots are named by scenario and start time; several runs are told apart; no wrap line on closed paths."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from cnc_tools.analysis.report import path_trace, run_labels, write_report
from cnc_tools.analysis.scoring import score_run
from cnc_tools.bagio.bag import read_bag
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.outputs import named_by_run_folder, score_record
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
START = "20261123T164500_000000Z"


@pytest.fixture(scope="module")
def full_circle() -> RunRecord:
    """Paper 000's circle to its end: the tool passes the closed contour's start point again."""
    return run_engine(load_scenario(ROOT / "scenarios" / "paper000_circle_high.yaml"))


def test_path_trace_breaks_where_the_path_length_wraps() -> None:
    s_m = np.array([0.0, 0.05, 0.099, 0.1, 0.0005, 0.0, 0.0])
    x_mm, y_um = path_trace(s_m, np.full(7, 1e-6), total_length_m=0.1)
    assert x_mm.size == 8 and np.isnan(x_mm[4]) and np.isnan(y_um[4])
    np.testing.assert_allclose(x_mm[[0, 3, 5]], [0.0, 100.0, 0.5])


def test_a_closed_circle_run_has_no_line_back_to_the_start(full_circle: RunRecord) -> None:
    series = score_run(full_circle).series
    length_m = full_circle.program.total_length_m
    assert np.abs(np.diff(series.path_length_m)).max() > 0.5 * length_m, "the raw series wraps"
    x_mm, _ = path_trace(series.path_length_m, series.error_m, length_m)
    steps_mm = np.diff(x_mm)
    finite = steps_mm[np.isfinite(steps_mm)]
    assert np.isnan(x_mm).sum() >= 1
    assert np.abs(finite).max() < 0.5 * length_m * 1e3, "no drawn segment spans half the contour"


def test_runs_of_the_same_name_get_distinct_labels(full_circle: RunRecord) -> None:
    twin = full_circle.with_(source=Path("elsewhere"))
    same = full_circle.with_()
    labels = run_labels([full_circle, twin, same])
    assert len(set(labels)) == 3
    assert all(label.startswith(full_circle.name) for label in labels)
    assert run_labels([full_circle]) == [full_circle.name]


def test_an_engine_run_folder_names_the_run_and_its_plots(full_circle: RunRecord, tmp_path: Path) -> None:
    run_dir = tmp_path / "bags" / "paper000_circle_high" / START
    scored = score_record(full_circle, run_dir)
    assert scored.run.name == f"paper000_circle_high/{START}"
    assert named_by_run_folder(scored.run, run_dir).name == scored.run.name, "named once"
    assert named_by_run_folder(full_circle, None) is full_circle
    files = write_report([scored.run, full_circle], tmp_path / "report", figures=["error_path"])
    assert [f.name for f in files] == ["contour_error_path.png"]


def test_a_run_folders_bag_is_named_by_scenario_and_start_time(circle_bag: Path, tmp_path: Path) -> None:
    bag = tmp_path / "bags" / "circle_scenario" / START / "bag"
    bag.mkdir(parents=True)
    shutil.copy(circle_bag / "metadata.yaml", bag / "metadata.yaml")
    shutil.copy(circle_bag / "circle.mcap", bag / "bag.mcap")
    (bag / "metadata.yaml").write_text((bag / "metadata.yaml").read_text().replace("circle.mcap", "bag.mcap"))
    assert read_bag(bag).name == f"circle_scenario/{START}"
    assert read_bag(bag / "bag.mcap").name == f"circle_scenario/{START}", "not 'bag'"
