"""The paper-001 bench: the quick bench, learning sessions that carry their state over, the stacks (engine only)."""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from cnc_contour_control.compensators import make_compensator
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_plant_sim.models.mass_friction import paper001_axes
from cnc_tools.bench.registry import BENCHES
from cnc_tools.reproductions.paper001 import runs as runs_module
from cnc_tools.reproductions.paper001.bench import GOAL_RATIO, TABLE_STACKS
from cnc_tools.reproductions.paper001.data import SCENARIOS, TABLE1_NETWORK, TABLES
from cnc_tools.reproductions.paper001.readings import (
    READINGS,
    discrete_poles,
    measure,
    reading_named,
    run_reading,
    stable_readings,
)
from cnc_tools.reproductions.paper001.runs import (
    PAPER000_SCENARIO,
    STACKS,
    SessionSpec,
    learning_runs,
    run_session,
    run_sessions,
    stack_scenario,
)
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
CIRCLE = ROOT / SCENARIOS["circle"]


@pytest.fixture(autouse=True)
def project_root(monkeypatch: pytest.MonkeyPatch) -> None:
    """The bench finds the scenarios under CNC_CONTOUR_ROOT."""
    monkeypatch.setenv("CNC_CONTOUR_ROOT", str(ROOT))


# ---------------------------------------------------------------- the quick bench


@pytest.fixture(scope="module")
def quick_bench(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, dict, Path]:
    """``cnc-contour bench paper001 --quick`` once for the module: printed text, JSON figures, output folder."""
    out = tmp_path_factory.mktemp("paper001")
    options = argparse.Namespace(name="paper001", quick=True, json=out / "figures.json", out=out / "run")
    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CNC_CONTOUR_ROOT", str(ROOT))
        with contextlib.redirect_stdout(printed):
            assert BENCHES["paper001"](options) == 0
    return printed.getvalue(), json.loads((out / "figures.json").read_text()), out / "run"


def test_quick_bench_prints_every_number_of_tables_2_and_3(quick_bench: tuple[str, dict, Path]) -> None:
    text, _, _ = quick_bench
    for table in TABLES.values():
        for column in table:
            assert f"{column.peak_mm:g}" in text and f"{column.ise:g}" in text
    for title in ("Table 2, line", "Table 3, circle", "goal (issue 8)", "sensitivities", "Fig. 8",
                  "paper 000's machine", "wall time"):
        assert title in text


def test_quick_bench_our_pid_rows_are_the_unit_studys_measure(quick_bench: tuple[str, dict, Path]) -> None:
    _, figures, _ = quick_bench
    for contour, path in SCENARIOS.items():
        expected = measure(run_engine(load_scenario(ROOT / path)), 1e-3)
        pid = next(r for r in figures["tables"][contour] if r["stack"] == "pid")
        assert pid["peak_mm"] == pytest.approx(expected["peak_mm"], rel=1e-12)
        assert pid["ise_mm2"] == pytest.approx(expected["ise_mm2"], rel=1e-12)
        assert pid["paper_peak_mm"] == TABLES[contour][0].peak_mm


def test_quick_bench_has_every_stack_at_its_checkpoints(quick_bench: tuple[str, dict, Path]) -> None:
    _, figures, out = quick_bench
    checkpoints = figures["plan"]["checkpoints"]
    for contour in SCENARIOS:
        rows = figures["tables"][contour]
        for stack in TABLE_STACKS:
            found = [r["run"] for r in rows if r["stack"] == stack]
            assert found == (checkpoints if STACKS[stack].learns else [1]), stack
        assert all(math.isfinite(r["peak_mm"]) and r["peak_mm"] > 0 for r in rows)
    for row in figures["goal"]:
        assert row["met"] == (row["ratio"] <= GOAL_RATIO)
    assert (out / "learning_curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(figures["fig8"]) == 6 and len(figures["paper000"]) == 3


def test_quick_bench_benches_the_network_in_every_stable_reading(quick_bench: tuple[str, dict, Path]) -> None:
    text, figures, _ = quick_bench
    rows = figures["readings"]
    assert {r["reading"] for r in rows} == {"mm_plant_um_gains", "si_plant_mm_gains"}
    assert "the network in every stable reading" in text
    for name in ("mm_plant_um_gains", "si_plant_mm_gains"):
        pid = next(r for r in rows if (r["reading"], r["contour"], r["network"]) == (name, "circle", "pid"))
        expected = run_reading(load_scenario(CIRCLE), reading_named(name))
        assert pid["peak_mm"] == pytest.approx(expected["peak_mm"], rel=1e-12)
        assert {r["contour"] for r in rows if r["reading"] == name} == {"line", "circle"}
    for row in rows:
        if row["network"] != "pid":
            assert row["holds"] == (row["peak_change"] <= row["paper_peak_change"])
            assert row["asked_runs"] in figures["plan"]["checkpoints"]


def test_the_stable_readings_are_those_whose_sampled_loop_is_stable() -> None:
    scenario = load_scenario(CIRCLE)
    stable = {r.name for r in stable_readings(scenario)}
    assert stable == {"mm_plant_um_gains", "si_plant_mm_gains"}
    for reading in READINGS:
        plant = reading.apply(scenario).plant
        radius = max(np.max(np.abs(discrete_poles(axis, reading, 1e-3)))
                     for axis in paper001_axes(plant.axes, plant.axis_overrides))
        assert (radius < 1.0) == (reading.name in stable), reading.name
    with pytest.raises(ConfigError, match="si_plant_mm_gains"):
        reading_named("SI")


# ---------------------------------------------------------------- sessions


@pytest.mark.parametrize("stack", ["nn", "ilc"])
def test_run_two_starts_from_run_ones_state_file(tmp_path: Path, stack: str) -> None:
    scenario = stack_scenario(load_scenario(CIRCLE), STACKS[stack])
    (first_scenario, first), (second_scenario, second) = list(learning_runs(scenario, 2, tmp_path))
    assert first_scenario.compensator.state_in == ""
    assert second_scenario.compensator.state_in == first_scenario.compensator.state_out
    assert Path(first_scenario.compensator.state_out).is_file()
    fresh = run_engine(scenario)
    assert np.array_equal(fresh.compensation.correction[0], first.compensation.correction[0])
    assert not np.array_equal(second.compensation.correction[0], fresh.compensation.correction[0])


def test_sessions_do_not_depend_on_the_worker_count(tmp_path: Path) -> None:
    def specs(folder: str) -> list[SessionSpec]:
        return [SessionSpec("a", "circle", "nn", 2, str(tmp_path / folder / "a")),
                SessionSpec("b", "line", "ilc", 2, str(tmp_path / folder / "b"))]

    one, two = run_sessions(specs("one"), workers=1), run_sessions(specs("two"), workers=2)
    assert {k: s.runs for k, s in one.items()} == {k: s.runs for k, s in two.items()}
    assert one["a"].runs[0] != one["a"].runs[1]


def test_session_keys_must_be_unique(tmp_path: Path) -> None:
    spec = SessionSpec("a", "circle", "pid", 1, str(tmp_path))
    with pytest.raises(ConfigError, match="unique"):
        run_sessions([spec, spec])


def test_a_faulted_run_ends_the_session_as_diverged(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = []

    def engine(scenario: object) -> object:
        calls.append(scenario)
        if len(calls) == 2:
            raise FaultError("plant: position x is nan")
        return run_engine(scenario)

    monkeypatch.setattr(runs_module, "run_engine", engine)
    session = run_session(SessionSpec("a", "circle", "nn", 4, str(tmp_path)))
    assert len(session.runs) == 2 and len(calls) == 2
    assert session.runs[1].diverged and "nan" in session.runs[1].fault and math.isnan(session.runs[1].peak_mm)
    assert session.at(4) == session.runs[1]


# ---------------------------------------------------------------- stacks and scenarios


@pytest.mark.parametrize("name", [name for name, stack in STACKS.items() if stack.params])
def test_every_stack_builds_its_compensator(name: str) -> None:
    stack = STACKS[name]
    compensator = make_compensator(stack.method, stack.params, ("x", "y"), 1e-3)
    for key, value in stack.params.items():
        assert getattr(compensator.config, key) == value


def test_paper_stack_is_section_2_3_as_printed() -> None:
    params = STACKS["nn-paper-mm"].params
    assert (params["eta"], params["alpha"], params["hidden_units"]) == (
        TABLE1_NETWORK["learning_rate"], TABLE1_NETWORK["momentum"], TABLE1_NETWORK["hidden"])
    assert params["beta"] == 1.0 and params["error_scale_per_m"] == 1e3 and params["output_input_scale"] == 1.0
    assert STACKS["nn-paper-um"].params == {**params, "error_scale_per_m": 1e6}


def test_pid_stack_drops_the_stages_and_file_stack_needs_a_section() -> None:
    with_stages = stack_scenario(load_scenario(CIRCLE), STACKS["nn"])
    assert with_stages.optional_stages == ("estimator", "compensator")
    assert stack_scenario(with_stages, STACKS["pid"]).optional_stages == ()
    with pytest.raises(ConfigError, match="needs a compensator section"):
        stack_scenario(load_scenario(CIRCLE), STACKS["file"])


def test_paper000_network_scenario_is_paper000_circle_high_plus_the_stages() -> None:
    ours = yaml.safe_load((ROOT / PAPER000_SCENARIO).read_text())
    paper000 = yaml.safe_load((ROOT / "scenarios" / "paper000_circle_high.yaml").read_text())
    own = ("name", "description", "paper", "estimator", "compensator")
    assert {k: v for k, v in ours.items() if k not in own} == {k: v for k, v in paper000.items() if k not in own}
    scenario = load_scenario(ROOT / PAPER000_SCENARIO)
    assert scenario.compensator.method == "neural" and scenario.estimator.method == "window"
