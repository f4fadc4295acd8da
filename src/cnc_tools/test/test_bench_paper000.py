"""The paper-000 benches: the paper's data, the runs, the views, the quick paths (engine only, fast).

No timing assertions. The node-graph path is the same runner as ``cnc-contour run``
(tested end to end elsewhere); here the engine stands in, scored by the same scorer.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.laws.fuzzy import RULE_BASES
from cnc_contour_control.motion.geometry import LineSegment, Program
from cnc_tools.analysis.scoring import score_run
from cnc_tools.bench.registry import BENCHES
from cnc_tools.cli.main import main as cli_main
from cnc_tools.reproductions.paper000.assumptions import VARIANTS
from cnc_tools.reproductions.paper000.data import EXPERIMENTS, TABLE2_AXES, TABLE4_GAINS, TABLE5, table5_row
from cnc_tools.reproductions.paper000.runs import (
    CONTROLLERS,
    VIEWS,
    apply_view,
    engine_recorded_run,
    eq9_program,
    feedforward_axes,
    get_controller,
    scenario_for,
    score_views,
)
from cnc_tools.reproductions.paper000.sweep import settings_of, table5_cases
from cnc_tools.runs.engine import run_engine

ROOT = Path(__file__).resolve().parents[3]
LINE_LOW = ROOT / "scenarios" / "paper000_line_low.yaml"


@pytest.fixture(autouse=True)
def project_root(monkeypatch: pytest.MonkeyPatch) -> None:
    """The benches find the scenarios under CNC_CONTOUR_ROOT."""
    monkeypatch.setenv("CNC_CONTOUR_ROOT", str(ROOT))


def _options(tmp_path: Path, name: str, **extra: object) -> argparse.Namespace:
    return argparse.Namespace(name=name, quick=True, engine=True, seeds=None, json=tmp_path / "out.json",
                              out=tmp_path / "run", **extra)


# ---------------------------------------------------------------- the paper's data


def test_table5_is_complete_and_has_its_scenarios() -> None:
    assert [(r.contour, r.feed) for r in TABLE5] == [
        (c, f) for c in ("line", "circle", "corner") for f in ("low", "high")]
    assert [r.feed_m_min for r in TABLE5] == [0.4, 0.9, 0.4, 1.3, 0.3, 0.6]
    for row in TABLE5:
        assert (ROOT / row.scenario).is_file()
        assert all(row.paper_value(c, m) > 0 for c in ("pid", "flc") for m in ("max", "rms"))
    assert table5_row("circle_high").paper_value("pid", "rms") == 27.7
    assert TABLE4_GAINS == {"kp": 2.4, "ki": 0.1, "kd": 6.7}
    assert TABLE2_AXES == {"x": (28.35, 0.055), "y": (28.96, 0.056)}


def test_experiments_have_their_ratios_and_scenarios() -> None:
    assert [(e.max_ratio_pid_to_flc, e.rms_ratio_pid_to_flc) for e in EXPERIMENTS] == [(2.1, None), (1.9, 3.5)]
    for experiment in EXPERIMENTS:
        assert (ROOT / experiment.scenario).is_file()


@pytest.mark.parametrize("call", [lambda: table5_row("square_low"), lambda: TABLE5[0].paper_value("lqr", "max"),
                                  lambda: get_controller("lqr")])
def test_unknown_names_are_refused(call: object) -> None:
    with pytest.raises(ConfigError, match="must be one of|reports pid/flc"):
        call()  # type: ignore[operator]  # a parametrised callable


# ---------------------------------------------------------------- controllers and scenarios


def test_controllers_cover_the_paper_feedforward_and_every_rule_base() -> None:
    assert {"pid", "flc", "pid+ff", "flc+ff"} <= set(CONTROLLERS)
    assert {f"flc:{name}" for name in RULE_BASES if name != "paper000"} <= set(CONTROLLERS)


def test_scenario_for_replaces_the_law_and_its_parameters() -> None:
    scenario = scenario_for(LINE_LOW, get_controller("flc"), seed=3)
    assert scenario.seed == 3 and scenario.plant.seed == 3
    assert {s.law for s in scenario.servos} == {"fuzzy"}
    assert all("kp" not in s.law_params for s in scenario.servos)


def test_feedforward_is_the_inverse_of_the_nominal_plant() -> None:
    scenario = scenario_for(LINE_LOW, get_controller("pid+ff"), seed=1)
    ff = {s.axis_name: (s.ff1, s.ff2) for s in scenario.servos}
    for axis, (gain, tau) in TABLE2_AXES.items():
        assert_allclose(ff[axis], (1.0 / gain, tau / gain))
    assert feedforward_axes(scenario.plant)["x"]["ff1"] == pytest.approx(1 / 28.35)


@pytest.mark.parametrize("variant", VARIANTS, ids=lambda v: v.name)
def test_every_assumption_variant_builds_valid_scenarios(variant: object) -> None:
    for case in table5_cases(quick=False):
        for controller in variant.controllers().values():  # type: ignore[attr-defined]  # a parametrised variant
            scenario_for(case.path, controller, 1, variant.overrides(case.name))  # type: ignore[attr-defined]  # a parametrised variant
    assert variant.view in VIEWS  # type: ignore[attr-defined]  # a parametrised variant


# ---------------------------------------------------------------- runs and views


def test_engine_run_is_scored_by_the_project_scorer_unchanged() -> None:
    scenario = scenario_for(LINE_LOW, get_controller("pid"), seed=1)
    result = run_engine(scenario)
    run = engine_recorded_run(scenario, result)
    assert run is result, "the engine gives the run record itself: no bridge between two shapes"
    assert run.backend == "engine" and run.integrity.complete
    whole, _ = score_views(run)["whole_run"]
    assert score_run(whole).contour.values_si == score_run(run).contour.values_si


def test_paper_view_scores_the_motion_only() -> None:
    scenario = scenario_for(LINE_LOW, get_controller("pid"), seed=1)
    run = engine_recorded_run(scenario)
    cut = apply_view(run, VIEWS["paper"])
    assert cut.joint_states.stamp_ns[-1] * 1e-9 <= scenario.make_interpolator().duration_s
    assert not cut.reference.done.any() and run.reference.done.any()
    assert cut.joint_states.stamp_ns.size < run.joint_states.stamp_ns.size
    later = apply_view(run, VIEWS["after_start"])
    assert later.joint_states.stamp_ns[0] == 500_000_000


def test_eq9_contour_ignores_running_past_the_end_of_a_line() -> None:
    line = Program("l", ("x", "y"), (LineSegment(np.zeros(2), np.array([0.01, 0.0]), 0.01),))
    past_end = np.array([[0.0101, 2e-5]])
    assert line.contour_distance(past_end)[0][0] == pytest.approx(math.hypot(1e-4, 2e-5))
    assert eq9_program(line).contour_distance(past_end)[0][0] == pytest.approx(2e-5)


def test_eq9_contour_keeps_a_closed_circle() -> None:
    scenario = scenario_for(ROOT / "scenarios" / "paper000_circle_low.yaml", get_controller("pid"), seed=1)
    assert eq9_program(scenario.program) is scenario.program


# ---------------------------------------------------------------- the benches' quick paths


def test_benches_are_registered() -> None:
    assert {"paper000", "paper000-pid", "paper000-assumptions"} <= set(BENCHES)


def test_seeds_must_be_at_least_one(tmp_path: Path) -> None:
    options = _options(tmp_path, "paper000")
    options.seeds = 0
    with pytest.raises(ConfigError, match="seeds must be an integer >= 1, got 0"):
        settings_of(options, 5)


def test_quick_pid_row_is_well_formed_and_printed_beside_the_paper(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert BENCHES["paper000-pid"](_options(tmp_path, "paper000-pid")) == 0
    out = capsys.readouterr().out
    table = json.loads((tmp_path / "out.json").read_text())["table"]
    assert [row["case"] for row in table] == ["line_low"]
    for metric, paper in (("max", 9.3), ("rms", 1.8)):
        cell = table[0][metric]
        assert cell["paper_blu"] == paper and f"{paper:.1f}" in out
        assert len(cell["ours_blu"]) == 1 and 0.0 < cell["ours_blu"][0] < 100.0
        assert cell["ratio_ours_to_paper"] == pytest.approx(cell["ours_blu"][0] / paper)
    assert (tmp_path / "run" / "figures" / "line_low" / "xy_trace.png").is_file()


def test_quick_paper000_scores_pid_and_flc_the_same_way(tmp_path: Path) -> None:
    assert cli_main(["bench", "paper000", "--quick", "--engine", "--json", str(tmp_path / "out.json"),
                     "--out", str(tmp_path / "run")]) == 0
    figures = json.loads((tmp_path / "out.json").read_text())
    runs = {r["controller"]: r for r in figures["runs"] if r["scenario"].startswith("paper000_line_low")}
    assert {"pid", "flc", "pid+ff", "flc+ff"} <= set(runs)
    assert {r["source"] for r in runs.values()} == {"engine"}
    assert len({tuple(sorted(r["max_blu"])) for r in runs.values()}) == 1  # same views for every controller
    row = figures["table5"][0]
    assert row["case"] == "line_low"
    assert row["max"]["flc_to_pid"] == pytest.approx(row["max"]["flc_blu"][0] / row["max"]["pid_blu"][0])
    assert row["max"]["paper_flc_to_pid"] == pytest.approx(6.6 / 9.3)
    assert [e["experiment"] for e in figures["experiments"]] == ["line27"]
