"""Paper 001's plant on the engine: the scenarios run, and the unit-reading study's claims hold."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import find_peaks

from cnc_plant_sim.models.mass_friction import paper001_axes
from cnc_tools.analysis.scoring import tracking_errors
from cnc_tools.reproductions.paper001.data import SCENARIOS, TABLE2, TABLE3, paper_result
from cnc_tools.reproductions.paper001.readings import (
    READINGS,
    continuous_poles,
    discrete_poles,
    measure,
    reading_table,
)
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[3]
PATHS = {**{c: ROOT / p for c, p in SCENARIOS.items()},
         "circle_cutting": ROOT / "scenarios/paper001/circle_cutting.yaml"}
READING = {r.name: r for r in READINGS}


def scenario(name: str) -> Scenario:
    return load_scenario(PATHS[name])


@pytest.mark.parametrize("name", sorted(PATHS))
def test_each_paper001_scenario_runs_with_finite_bounded_errors(name: str) -> None:
    record = run_engine(scenario(name))
    assert record.summary["plant"]["model"] == "paper001" and record.summary["plant"]["length_unit"] == "mm"
    assert np.all(np.isfinite(record.joint_states.position_m))
    result = measure(record, 1e-3)
    assert result["broke_away"] and not result["diverged"]
    assert 0.0 < result["peak_mm"] < 0.6  # measured 0.36-0.41 mm (the start transient of the PID)
    assert math.isfinite(result["ise_mm2"]) and result["ise_mm2"] > 0.0


def test_the_paper_values_are_tables_2_and_3() -> None:
    assert [(r.peak_mm, r.ise) for r in TABLE2] == [(0.0961, 3.3009), (0.0767, 2.3005), (0.0321, 1.2825)]
    assert [(r.peak_mm, r.ise) for r in TABLE3] == [(0.0724, 17.8285), (0.0445, 7.4691), (0.0373, 5.1139)]
    assert paper_result("circle", "pid+nn", 50).peak_mm == 0.0373


def test_in_consistent_si_the_loop_is_unstable_and_the_axes_never_break_away() -> None:
    si = READING["si"]
    x = paper001_axes(("x",), {})[0]
    coefficients = np.poly(continuous_poles(x, si)) * x.mass
    np.testing.assert_allclose(coefficients, [0.45, 0.02, 5.0, 20.0], rtol=1e-9)  # 0.45s³ + 0.02s² + 5s + 20
    assert np.max(continuous_poles(x, si).real) > 0.0
    record = run_engine(si.apply(scenario("line")))
    result = measure(record, 1e-3)
    assert not result["broke_away"] and np.all(record.joint_states.position_m == 0.0)
    assert result["peak_mm"] == 0.0  # the start lies on the line: the contour error does not see a stuck machine
    assert result["tracking_max_mm"] > 30.0  # ... the tracking error does (45 mm·cos 45° by the end)


def test_gains_per_um_on_the_si_plant_diverge_at_1_ms_though_the_continuous_loop_is_stable() -> None:
    reading = READING["si_plant_um_gains"]
    x = paper001_axes(("x",), {})[0]
    assert np.max(continuous_poles(x, reading).real) < 0.0
    assert np.max(np.abs(discrete_poles(x, reading, 1e-3))) > 1.0
    assert measure(run_engine(reading.apply(scenario("line"))), 1e-3)["diverged"]


def test_the_discrete_poles_give_the_decay_the_engine_shows_without_friction() -> None:
    reading = READING["mm_plant_um_gains"]
    no_friction = {a: {"coulomb_n": 0.0, "stribeck_n": 0.0} for a in ("x", "y")}
    run = reading.apply(scenario("line")).variant({"plant": {"axis_overrides": no_friction},
                                                   "limits": {"max_acceleration_mm_s2": 1.0e6}})
    _, error = tracking_errors(run_engine(run))
    x = error[:900, 0] - np.convolve(error[:900, 0], np.ones(60) / 60, mode="same")  # the oscillation alone
    peaks, _ = find_peaks(x[50:850])
    measured = (x[50:850][peaks[5]] / x[50:850][peaks[0]]) ** (1.0 / (peaks[5] - peaks[0]))
    radius = np.sort(np.abs(discrete_poles(paper001_axes(("x",), {})[0], reading, 1e-3)))[-2]  # the oscillating pair
    assert measured == pytest.approx(radius, abs=5e-4)  # measured 0.99358 against 0.99360


def test_the_reading_table_puts_ours_beside_the_paper() -> None:
    rows = reading_table([READING["mm_plant_um_gains"], READING["si_plant_mm_gains"]],
                         {c: scenario(c) for c in ("line", "circle")})
    assert [(r["reading"], r["contour"]) for r in rows] == [
        ("mm_plant_um_gains", "line"), ("mm_plant_um_gains", "circle"),
        ("si_plant_mm_gains", "line"), ("si_plant_mm_gains", "circle")]
    assert all(r["paper_peak_mm"] == paper_result(r["contour"]).peak_mm for r in rows)
    assert all(r["spectral_radius"] < 1.0 and r["max_real_pole"] < 0.0 for r in rows)  # both stable at 1 ms
    chosen, si_mm = rows[1], rows[3]
    assert si_mm["stops"] > 0 and chosen["stops"] == 0  # stick-slip on the SI plant, none on the mm plant
    assert si_mm["peak_mm"] > 2.0 * chosen["peak_mm"]  # measured 1.59 against 0.38 mm on the circle
