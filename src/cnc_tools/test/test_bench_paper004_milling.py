"""Benches paper004-milling and paper004-speed: the rows they measure, on short runs (tier 1, engine only)."""
from __future__ import annotations

import numpy as np
import pytest

from cnc_tools.bench.registry import BENCHES
from cnc_tools.reproductions.paper004.milling import CASES, base_scenario, measure
from cnc_tools.reproductions.paper004.speed import step_costs_us
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import Scenario

SHORT = {"duration_s": 2.0, "plant": {"cutting": {"depth_schedule": [[0.0, 1.0], [1.0, 2.0]]}}}


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    return base_scenario(quick=True).variant(SHORT)


def test_the_benches_are_registered() -> None:
    assert {"paper004-milling", "paper004-speed"} <= set(BENCHES)


def test_a_row_scores_contour_and_force_per_depth_segment(scenario: Scenario) -> None:
    run = run_engine(scenario)
    assert scenario.force_regulator is not None
    row = measure("PI, 4-bit", run, scenario.force_regulator.setpoint.reference_n)
    assert [s["depth_mm"] for s in row.segments] == [1.0, 2.0]
    assert run.reference is not None and run.reference.feed_override_ratio is not None
    second = run.time_s >= 1.0
    assert row.segments[1]["mean_override"] == pytest.approx(float(np.mean(run.reference.feed_override_ratio[second])))
    assert row.mean_override == pytest.approx(float(np.mean(run.reference.feed_override_ratio)))
    assert 0.0 < row.contour_rms_um <= row.contour_max_um
    assert min(s["contour_rms_um"] for s in row.segments) <= row.contour_rms_um <= max(
        s["contour_rms_um"] for s in row.segments)
    assert row.path_mm > 0.9 * 2.0 * 1200.0 / 60.0 * float(np.mean(run.reference.feed_override_ratio))


def test_the_regulator_brings_the_deeper_cut_towards_the_reference(scenario: Scenario) -> None:
    variants = dict(CASES)
    rows = {}
    for name in ("no regulator", "PI, 4-bit"):
        run = run_engine(variants[name](scenario, rows))
        rows[name] = measure(name, run, 200.0)
    free, regulated = (rows[name].segments[1]["mean_n"] for name in ("no regulator", "PI, 4-bit"))
    assert free > 280.0 and abs(regulated - 200.0) < 0.5 * abs(free - 200.0)
    assert rows["no regulator"].mean_override == 1.0
    held = variants["constant override"](scenario, rows)
    assert held.force_regulator is None and held.feed_override is not None
    assert held.raw["feed_override"]["schedule"] == [[0.0, round(rows["PI, 4-bit"].mean_override, 3)]]


def test_the_speed_bench_times_every_law_beside_both_servos() -> None:
    costs = step_costs_us(steps=1000, repeats=1)
    assert set(costs) == {"regulator smc, 4-bit", "regulator smc_integral, 4-bit",
                          "regulator adaptive, 4-bit", "regulator pi, 4-bit",
                          "servo P (turning)", "servo PID (paper 000)"}
    assert all(0.0 < us < 1.0e4 for us in costs.values())
