"""The score's reference deviation: a blended run (G64 P) inside its tolerance, an exact-stop run (G61) on the path,
the interpolator's configured tolerance carried by the engine's record, and the verdict line when it is exceeded."""
from __future__ import annotations

import csv
import dataclasses
import io
from pathlib import Path

import numpy as np
import pytest

from cnc_tools.analysis.scoring import score_run
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import Scenario, load_scenario

SHOP = Path(__file__).resolve().parents[3] / "scenarios" / "gcode_shop.yaml"


def shop_variant(g64: str, interpolator: dict | None = None) -> Scenario:
    """gcode_shop with ``G64 P0.01`` replaced by ``g64`` (and an interpolator section merged)."""
    scenario = load_scenario(SHOP)
    program = dict(scenario.raw["program"])
    program["gcode"] = program["gcode"].replace("G64 P0.01", g64)
    return scenario.variant({"interpolator": interpolator or {}}, program=program)


@pytest.fixture(scope="module")
def blended() -> RunRecord:
    return run_engine(load_scenario(SHOP))


def test_a_blended_run_reports_its_deviation_inside_the_tolerance(blended: RunRecord) -> None:
    score = score_run(blended)
    deviation = score.deviation
    assert deviation is not None and deviation.tolerance_m == pytest.approx(1e-5)
    exact = blended.program.contour_distance(blended.reference.position_m)[0]
    assert deviation.max_m == pytest.approx(float(np.max(exact)), rel=1e-12)
    assert deviation.values_si["rms"] == pytest.approx(float(np.sqrt(np.mean(exact ** 2))), rel=1e-12)
    assert 1e-7 < deviation.max_m <= 1e-5 + 1e-9 and deviation.values_si["rms"] < deviation.max_m
    assert not deviation.exceeded and deviation.verdict() is None
    assert "reference deviation from the programmed path" in score.to_table()
    assert "over its path tolerance" not in score.to_table()
    data = score.to_dict()["reference_deviation"]
    assert data["tolerance_um"] == pytest.approx(10.0) and data["max_um"] == pytest.approx(deviation.max_m * 1e6)
    rows = list(csv.DictReader(io.StringIO(score.to_csv())))
    assert {r["metric"] for r in rows if r["scope"] == "reference_deviation"} == {"max", "rms", "tolerance"}


def test_an_exact_stop_run_stays_on_the_path() -> None:
    score = score_run(run_engine(shop_variant("G61")))
    deviation = score.deviation
    assert deviation is not None and deviation.tolerance_m == 0.0
    assert deviation.max_m < 1e-12 and not deviation.exceeded
    assert "path tolerance 0 (exact stop)" in score.to_table()


def test_the_engine_records_the_configured_tolerance() -> None:
    run = run_engine(shop_variant("", {"path_tolerance_mm": 0.005}))
    deviation = score_run(run).deviation
    assert run.program.path_tolerance_m == pytest.approx(5e-6)
    assert deviation is not None and deviation.tolerance_m == pytest.approx(5e-6)
    assert 1e-7 < deviation.max_m <= 5e-6 + 1e-9


def test_a_deviation_over_the_tolerance_is_a_verdict_line(blended: RunRecord) -> None:
    tight = blended.with_(program=dataclasses.replace(blended.program, path_tolerance_m=2e-6))
    score = score_run(tight)
    assert score.deviation is not None and score.deviation.exceeded
    assert "verdict: the reference deviates" in score.to_table() and "over its path tolerance 2 µm" in score.to_table()
    assert score.to_dict()["reference_deviation"]["exceeded"] is True
    unknown = score_run(blended.with_(program=dataclasses.replace(blended.program, path_tolerance_m=None)))
    assert unknown.deviation is not None and not unknown.deviation.exceeded
    assert "path tolerance not recorded" in unknown.to_table()
