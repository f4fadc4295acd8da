"""Friction identification (paper 000, Section 2): refusals, Eq. (1a) on engine runs, one node-graph run, fit, table."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_plant_sim.models.friction import paper000_x, paper000_y
from cnc_tools.cli import identify_friction as fic
from cnc_tools.cli.main import main
from cnc_tools.identification import friction as fid
from cnc_tools.identification import friction_curve as fcurve

#: Quantisation (8-bit DAC) bounds the error of one nominal-plant point (measured: <= 0.28 DAC).
QUANTISATION_DAC = 0.3


def _config(**overrides: object) -> fid.IdentificationConfig:
    return fid.IdentificationConfig(**{"speeds_mm_s": (1.0, 6.0, 16.0), "seeds": (), **overrides})  # type: ignore[arg-type]  # the config's own keywords


def _template(**plant: object) -> dict:
    template = copy.deepcopy(fid.DEFAULT_TEMPLATE)
    template["plant"].update(plant)
    return template


def _engine_points(config: fid.IdentificationConfig, template: dict | None = None) -> list[fid.FrictionPoint]:
    constants, runs = fid.plan_runs(template or fid.DEFAULT_TEMPLATE, config)
    return [fic.engine_point(run, constants, config) for run in runs]


# =========================================================================== refusals
@pytest.mark.parametrize(("overrides", "message"), [
    ({"speeds_mm_s": (0.0,)}, r"speeds_mm_s\[0\] must be > 0, got 0.0"),
    ({"speeds_mm_s": (2.0, -1.0)}, r"speeds_mm_s\[1\] must be > 0, got -1.0"),
    ({"speeds_mm_s": ()}, r"speeds_mm_s must hold at least one speed"),
    ({"speeds_mm_s": (2.0, 2.0)}, r"speeds_mm_s must be distinct"),
    ({"kp_dac_per_count": 0.0}, r"kp_dac_per_count must be > 0, got 0.0"),
    ({"window_s": -1.0}, r"window_s must be > 0, got -1.0"),
    ({"settle_s": -0.1}, r"settle_s must be >= 0, got -0.1"),
    ({"seeds": (1, -2)}, r"seeds\[1\] must be an integer >= 0, got -2"),
])
def test_bad_options_are_refused_naming_the_key(overrides: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        _config(**overrides)


def test_speed_beyond_the_velocity_limit_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"speeds_mm_s\[1\] must be <= limits.max_velocity_mm_min/60 = 33.333 mm/s "
                                          r"on axis x, got 40.0"):
        fid.plan_runs(fid.DEFAULT_TEMPLATE, _config(speeds_mm_s=(1.0, 40.0)))
    with pytest.raises(ConfigError, match=r"speeds_mm_s\[0\] must be <= limits.max_velocity_mm_min/60"):
        fid.plan_runs(fid.DEFAULT_TEMPLATE, _config(speeds_mm_s=(40.0,)))


def test_speed_beyond_the_dac_range_is_refused() -> None:
    template = copy.deepcopy(fid.DEFAULT_TEMPLATE)
    template["limits"]["max_velocity_mm_min"] = 6000.0
    with pytest.raises(ConfigError, match=r"speeds_mm_s\[0\] must be <= 30.1[0-9]* mm/s, .*servo.output_limit = 127"):
        fid.plan_runs(template, _config(speeds_mm_s=(32.0,), seeds=(1,)))


def test_unknown_axis_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"axis must be one of \['x', 'y'\], got 'z'"):
        fid.plan_runs(fid.DEFAULT_TEMPLATE, _config(axis="z"))


def test_plan_runs_every_speed_both_ways_on_nominal_and_varied_plants() -> None:
    constants, runs = fid.plan_runs(fid.DEFAULT_TEMPLATE, _config(axis="y", seeds=(3,)))
    assert (constants.gain_blu_s_per_dac, constants.encoder_counts_per_blu) == (28.96, 1.0)
    assert [r.velocity_mm_s for r in runs] == [-16.0, -6.0, -1.0, 1.0, 6.0, 16.0] * 2
    nominal, varied = runs[0].scenario, runs[-1].scenario
    assert nominal.plant.variation.gain_pct == 0.0 and varied.plant.variation.friction_pct == 8.0
    assert varied.seed == 3 and all(s.law == "p" and s.ff1 == 0.0 for s in nominal.servos)
    end = nominal.program.segments[0].end_m
    assert end[0] == 0.0 and end[1] < -0.016 * 3.0, "a line along -y covering ramp, settle and window"


# =========================================================================== Eq. (1a) on engine runs
@pytest.fixture(scope="module")
def x_points() -> list[fid.FrictionPoint]:
    return _engine_points(_config(seeds=(1, 2, 3)))


def test_nominal_plant_recovers_eq15_within_the_quantisation(x_points: list[fid.FrictionPoint]) -> None:
    nominal = [p for p in x_points if p.seed is None]
    assert len(nominal) == 6 and all(p.status == "steady" for p in nominal)
    for p in nominal:
        assert p.model_dac == pytest.approx(paper000_x().force(p.velocity_mm_s))
        assert abs(p.deviation_dac) < QUANTISATION_DAC, p
        assert abs(p.deviation_dac + p.quantisation_dac) < 0.05, "the error is the DAC rounding's mean bias"


def test_identified_curve_matches_the_drawn_model_within_the_run_to_run_band(
        x_points: list[fid.FrictionPoint]) -> None:
    summaries = fcurve.summarise(x_points)
    for s in summaries:
        assert abs(s.nominal.deviation_dac) <= s.half_range_dac, s
        for p in s.varied:
            assert p.friction_scale != 1.0
            assert abs(p.friction_true_gain_dac - p.model_dac) < QUANTISATION_DAC, "with the drawn K: exact"
            assert abs(p.deviation_dac) <= 0.06 * abs(p.velocity_mm_s) * 100 / 28.35 + QUANTISATION_DAC, \
                "with the nominal K: off by at most the K variation's share of V_r/K"


def test_y_axis_is_identified_against_its_own_friction() -> None:
    points = _engine_points(_config(axis="y", speeds_mm_s=(3.0,)))
    for p in points:
        assert p.model_dac == pytest.approx(paper000_y().force(p.velocity_mm_s))
        assert abs(p.deviation_dac) < QUANTISATION_DAC


@pytest.mark.parametrize(("speed_mm_s", "status"), [(0.01, "stuck"), (0.05, "stick-slip"), (0.5, "steady")])
def test_near_zero_speeds_report_stick_slip(speed_mm_s: float, status: str) -> None:
    points = _engine_points(_config(speeds_mm_s=(speed_mm_s,)))
    assert [p.status for p in points] == [status, status]


@pytest.mark.parametrize(("stopped", "ratio", "drift", "status"), [
    (0.0, 1.0, 0.0, "steady"), (0.04, 1.04, 0.4, "steady"), (0.2, 1.0, 0.0, "stick-slip"),
    (0.0, 0.9, 0.0, "stick-slip"), (0.0, 1.0, 0.8, "stick-slip"), (1.0, 0.0, 0.0, "stuck")])
def test_classify(stopped: float, ratio: float, drift: float, status: str) -> None:
    assert fid.classify(stopped, ratio, drift) == status


def test_window_is_the_constant_speed_part_after_settling() -> None:
    t = np.arange(0.0, 4.0, 0.01)
    speed = np.clip(np.minimum(t, 3.5 - t), 0.0, 0.5) * 2e-3  # ramp up to 0.5 s, cruise, ramp down from 3.0 s
    trace = fid.AxisTrace(t, np.zeros_like(t), np.zeros_like(t), speed, np.zeros_like(t))
    window = t[fid.window_mask(trace, 1.0, 1.0)]
    assert window[0] == pytest.approx(1.5) and window[-1] == pytest.approx(3.0)


# =========================================================================== the node graph
@pytest.mark.e2e
def test_node_graph_run_gives_the_engine_point(tmp_path: Path) -> None:
    config = _config(speeds_mm_s=(4.0,))
    constants, runs = fid.plan_runs(fid.DEFAULT_TEMPLATE, config)
    graph = fic.graph_point(runs[1], constants, config, tmp_path / "run", None)
    engine = fic.engine_point(runs[1], constants, config)
    assert (tmp_path / "run" / "bag" / "metadata.yaml").is_file()
    assert graph.status == "steady" and graph.samples == engine.samples
    assert graph.friction_dac == pytest.approx(engine.friction_dac, abs=1e-9)
    assert abs(graph.deviation_dac) < QUANTISATION_DAC


# =========================================================================== fit and table
def _exact_points(speeds: tuple[float, ...]) -> list[fid.FrictionPoint]:
    model = paper000_x()
    return [fid.FrictionPoint("nominal", None, v, 0.0, 0.0, model.force(v), model.force(v), 0.0, 0.0,
                              model.force(v), model.force(v), 1.0, v, 0.0, 0.0, 100, "steady")
            for s in speeds for v in (-s, s)]


def test_fit_recovers_the_eq15_coefficients() -> None:
    positive, negative = fcurve.fit_curve(_exact_points(fid.DEFAULT_SPEEDS_MM_S))
    np.testing.assert_allclose(positive.coefficients_dac, (0.05, -1.16, 20.49), atol=1e-9)
    np.testing.assert_allclose(negative.coefficients_dac, (-0.04, -1.00, -18.27), atol=1e-9)
    assert (positive.high_dac, negative.high_dac) == (pytest.approx(13.95), pytest.approx(-11.84))
    assert positive.limit_speed_mm_s == negative.limit_speed_mm_s == 12.25


def test_fit_needs_three_steady_speeds_per_branch() -> None:
    with pytest.raises(ConfigError, match="needs >= 3 steady speeds"):
        fcurve.fit_curve(_exact_points((1.0, 2.0)))


def test_table_round_trips_and_runs_as_a_plant_friction(tmp_path: Path) -> None:
    fits = fcurve.fit_curve(_exact_points(fid.DEFAULT_SPEEDS_MM_S))
    written = fcurve.write_table(tmp_path / "t.yaml", fcurve.fitted_table(fits, 20.0), fits, {"axis": "x"})
    table = fcurve.load_table(written)
    model = paper000_x()
    for v in (-20.0, -11.0, -3.3, -0.2, 0.2, 3.3, 11.0, 20.0):
        assert table.force(v) == pytest.approx(model.force(v), abs=0.02)
    assert (table.breakaway_positive, table.breakaway_negative) == (pytest.approx(20.49), pytest.approx(-18.27))
    template = _template(axis_overrides={"x": {"friction": "table", "friction_params": table.to_params()}})
    for p in _engine_points(_config(speeds_mm_s=(2.0,)), template):
        assert abs(p.friction_dac - table.force(p.velocity_mm_s)) < QUANTISATION_DAC, "identifying the table returns it"


# =========================================================================== the subcommand
def test_cli_engine_writes_points_figure_and_table(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, table = tmp_path / "out", tmp_path / "table.yaml"
    code = main(["identify-friction", "--engine", "--speeds", "0.5,2,6,16", "--seeds", "2", "--out", str(out),
                 "--write-table", str(table)])
    printed = capsys.readouterr().out
    assert code == 0, printed
    for name in ("points.csv", "curve.csv", "friction_velocity.png", "friction_table.yaml"):
        assert (out / name).stat().st_size > 0 and f"wrote: {out / name}" in printed
    assert len((out / "points.csv").read_text().splitlines()) == 1 + 8 * 3
    assert fcurve.load_table(table).breakaway_positive > 18.0


def test_cli_refuses_a_non_positive_speed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["identify-friction", "--engine", "--speeds=2,-1", "--out", str(tmp_path / "o")]) == 2
    assert "speeds_mm_s[1] must be > 0, got -1.0" in capsys.readouterr().err
