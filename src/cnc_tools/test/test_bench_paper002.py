"""The paper-002 bench: its measures, its cases, the engine against the design's model, and the quick bench."""
from __future__ import annotations

import argparse
import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.laws import law_config
from cnc_contour_control.laws.loop_report import loop_figures
from cnc_tools.bench.registry import BENCHES
from cnc_tools.reproductions.paper002 import data, tables
from cnc_tools.reproductions.paper002.bench import design_config, sweep_prediction
from cnc_tools.reproductions.paper002.measures import lock_in_amplitude
from cnc_tools.reproductions.paper002.runs import METHODS, Case, run_case, scenario_for

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(autouse=True)
def project_root(monkeypatch: pytest.MonkeyPatch) -> None:
    """The bench finds the scenario under CNC_CONTOUR_ROOT."""
    monkeypatch.setenv("CNC_CONTOUR_ROOT", str(ROOT))


# ---------------------------------------------------------------- measures


def test_lock_in_finds_a_sinusoid_under_a_ramp_and_noise() -> None:
    t = np.arange(1500) * 1e-3
    rng = np.random.default_rng(0)
    x = 0.37 * np.sin(2 * np.pi * 50.0 * t + 0.4) + 80.0 * t ** 2 + 3.0 + rng.normal(0.0, 0.3, t.size)
    assert lock_in_amplitude(t, x, 50.0) == pytest.approx(0.37, abs=0.02)
    assert lock_in_amplitude(t, x - 0.37 * np.sin(2 * np.pi * 50.0 * t + 0.4), 50.0) < 0.03
    with pytest.raises(ConfigError, match="lock-in needs >= 2 periods of f_hz 50 in its window, got 0.03 s"):
        lock_in_amplitude(t[:31], x[:31], 50.0)


# ---------------------------------------------------------------- cases


def test_a_case_sets_the_law_per_axis_the_inertia_and_the_spindle() -> None:
    case = Case("t/mbda_pdc", "line", "mbda_pdc", inertia_error=0.2, plant_rpm=1575.0, design_rpm=1500.0,
                step=(1.0, 1650.0), encoder=False)
    scenario = scenario_for(case)
    configs = [law_config(s.law, s.law_params) for s in scenario.servos]
    assert [c.model for c in configs] == ["x", "y"]  # each axis its own P_n
    assert [c.spindle_rpm for c in configs] == [1500.0, 1500.0]
    x = scenario.plant.axis_overrides["x"]
    nominal = scenario_for(Case("t/p", "line", "p", inertia_error=0.0)).plant.axis_overrides["x"]
    assert x["loop"] == "pi"
    assert x["torque_per_inertia"] == pytest.approx(nominal["torque_per_inertia"] / 1.2)
    loop = scenario.plant.velocity_loop
    assert loop is not None
    assert (loop.spindle_rpm, loop.spindle_schedule_rpm, loop.encoder_pulse_m) == (1575.0, (1650.0,), 0.0)
    assert tuple(scenario.program.end_m * 1e3) == pytest.approx(data.LINE_TO_MM)
    assert case.f_d_hz == pytest.approx(55.0)


def test_the_scenarios_periodic_share_of_the_error_is_the_papers() -> None:
    """On the line at constant speed the P loop's floor / RMS is the paper's (a)/(b) (the amplitude's reason)."""
    floor = run_case(Case("line/p/ref", "line", "p", periodic=False)).measure.rms_pulse
    total = run_case(Case("line/p", "line", "p")).measure.rms_pulse
    paper = data.PAPER_RMS_PULSE["a"] / data.PAPER_RMS_PULSE["b"]
    assert floor / total == pytest.approx(paper, rel=0.05)


@pytest.mark.parametrize("law", ["dob", "dob_pdc"])
def test_the_engine_removes_what_the_design_model_predicts(law: str) -> None:
    """The law's timing matches the plant's: the f_d line removed on the line is design_report's removal."""
    bare = run_case(Case("line/p", "line", "p", encoder=False)).measure.fd_pulse
    ours = run_case(Case(f"line/{law}", "line", law, encoder=False)).measure.fd_pulse
    predicted = [loop_figures(design_config(law, axis), data.F_D_HZ, 0.0, 50)["removal_at_fd"] for axis in "xy"]
    assert min(predicted) - 0.01 <= 1.0 - ours / bare <= max(predicted) + 0.01


def test_the_sweep_judges_each_axis_with_its_own_model() -> None:
    """MBDA+PDC at 75 Hz works on X (disturbance peak 1.94) but not on Y (2.48), so not on both; the DOB at 73 Hz
    removes 0.1 % nominally but makes the line 14-16 % worse at +20 % inertia."""
    per_axis = {axis: sweep_prediction(("mbda_pdc", 75.0, axis, 100)) for axis in ("x", "y")}
    assert per_axis["x"]["disturbance_peak"] < data.GOAL_PEAK < per_axis["y"]["disturbance_peak"]
    worst = tables.worst_of_axes(per_axis)
    assert (worst["disturbance_peak"], worst["disturbance_peak_axis"]) == (per_axis["y"]["disturbance_peak"], "y")
    assert tables.works_summary({"mbda_pdc": {75.0: worst}}) == {"mbda_pdc": {"x": [75.0], "y": [], "both": [],
                                                                              "worse": []}}
    dob = tables.worst_of_axes({axis: sweep_prediction(("dob", 73.0, axis, 100)) for axis in ("x", "y")})
    assert dob["removal_at_fd"] > 0.0 > -0.13 > dob["removal_at_fd_worst"]  # +20 % inertia: the DOB amplifies
    assert tables.works_summary({"dob": {73.0: dob}})["dob"]["worse"] == [73.0]


# ---------------------------------------------------------------- the quick bench


@pytest.fixture(scope="module")
def quick_bench(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, dict, Path]:
    """``cnc-contour bench paper002 --quick`` once for the module: printed text, JSON figures, output folder."""
    out = tmp_path_factory.mktemp("paper002")
    options = argparse.Namespace(name="paper002", quick=True, json=out / "figures.json", out=out / "run")
    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CNC_CONTOUR_ROOT", str(ROOT))
        with contextlib.redirect_stdout(printed):
            assert BENCHES["paper002"](options) == 0
    return printed.getvalue(), json.loads((out / "figures.json").read_text()), out / "run"


def test_quick_bench_prints_the_papers_numbers_beside_ours(quick_bench: tuple[str, dict, Path]) -> None:
    printed, figures, _ = quick_bench
    for value in (*data.PAPER_RMS_PULSE.values(), *data.W_X, *data.W_Y):
        assert f"{value:.3f}" in printed or f"{value:.4f}" in printed, value
    for contour in ("line", "circle"):
        rows = {r["run"]: r for r in figures["main"][contour]}
        assert [rows[run]["paper_rms_pulse"] for run in data.PAPER_READING.values()] == \
            list(data.PAPER_RMS_PULSE.values())
        assert rows["p"]["fd_pulse"] > 20 * rows["reference"]["fd_pulse"]  # the disturbance is there
        for law in ("pdc", "dob_pdc", "mbda_pdc"):
            assert rows[law]["fd_removal"] > 0.9, (contour, law)
        assert rows["dob"]["fd_removal"] == pytest.approx(rows["dob"]["removal_at_fd"], abs=0.05)


def test_quick_bench_gives_the_papers_rms_share_on_the_line(quick_bench: tuple[str, dict, Path]) -> None:
    """With the paper's periodic share of the error, adding the PDC removes the paper's share of the RMS (±5 points),
    and the f_d line nearly all."""
    _, figures, _ = quick_bench
    shares = {row["pair"]: row for row in figures["shares"]}
    for base, with_pdc in data.PDC_PAIRS:
        share = shares[f"{METHODS[base]} -> {METHODS[with_pdc]}"]
        assert share["line"]["plain"] == pytest.approx(share["paper_plain"], abs=0.05), share
        assert share["line"]["fd_line"] > 0.99, share


def test_quick_bench_checks_the_goals_with_measured_figures(quick_bench: tuple[str, dict, Path]) -> None:
    printed, figures, _ = quick_bench
    for row in figures["inertia"]:
        assert row["met"] == (row["worst"] >= data.GOAL_REMOVAL and row["stable"]
                              and row["sensitivity_peak"] <= 2.0 and row["disturbance_peak"] <= 2.0)
        assert min(v for v in row["removal"].values()) > 0.9
    for row in figures["spindle"]:
        assert row["met"] == (row["worst"] >= data.GOAL_SPINDLE_REMOVAL)
        assert all(v > row["worst"] - 1e-12 for v in row["held"].values())
    for row in figures["tracked"]:  # f_d estimated on line, no schedule: the ±7 % goal, and not met without it
        assert row["met"] and row["worst_tracked"] >= 0.9 and row["sensitivity_peak"] <= 2.0, row
        assert min(row["held"].values()) < 0.9 < min(row["tracked"].values()), row
    assert "WITHOUT a schedule" in printed
    assert "best stack:" in printed and "spindle step" in printed
    step = {r["law"]: r for r in figures["steps"]}
    assert 0.0 < step["mbda_pdc"]["removal"] < 0.95  # the old design after a 10 % step: part of the line only
    for row in figures["spindle_online"]:  # the servo follows the spindle: the PDC redesigns on line
        assert row["met"] and min(row["online"].values()) > min(row["held"].values())
    online = {r["law"]: r for r in figures["steps_online"]}["mbda_pdc"]
    assert online["removal_online"] > online["removal_design"] + 0.05
    assert online["recovery_s_online"] <= 1.0
    assert online["recovery_s_design"] != online["recovery_s_design"], "nan: the old design never gets back"


def test_quick_bench_writes_the_plots(quick_bench: tuple[str, dict, Path]) -> None:
    _, _, out = quick_bench
    for name in ("traces_line", "traces_circle", "pdc_design_x", "disturbance_responses_x", "fd_sweep",
                 "spindle_step"):
        path = out / f"{name}.png"
        assert path.stat().st_size > 10_000, path
