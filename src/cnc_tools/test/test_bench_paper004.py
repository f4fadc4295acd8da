"""The paper-004 bench: the floors against issue 12's estimates, the measures, the runs, the quick bench."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from cnc_contour_control.force import DepthSchedule, FirstOrderLag
from cnc_tools.bench.registry import BENCHES
from cnc_tools.reproductions.paper004 import data
from cnc_tools.reproductions.paper004.floors import level_forces_n, levels_in_band, step_floor
from cnc_tools.reproductions.paper004.metrics import segments
from cnc_tools.reproductions.paper004.runs import MAIN_CASES, REST_CASES, paper_model, run_case, switch
from cnc_tools.reproductions.paper004.sim import Traces, feed_stop_response


@pytest.mark.parametrize("depths", sorted(data.ISSUE_FLOOR_OVERSHOOT_PCT))
def test_floors_match_issue_12s_estimates(depths: tuple[float, float]) -> None:
    floor = step_floor(paper_model(), depths, data.REFERENCE_N, data.BAND_FRACTION)
    assert floor.overshoot_pct == pytest.approx(data.ISSUE_FLOOR_OVERSHOOT_PCT[depths], abs=0.5)
    assert floor.settling_s == pytest.approx(data.ISSUE_FLOOR_SETTLING_S[depths], abs=0.01)


def test_levels_match_issue_12s_estimates() -> None:
    model, levels = paper_model(), switch(True)
    assert 100.0 * model.steady_ratio(500.0, 1.0) == pytest.approx(data.ISSUE_RATIO_AT_1MM_PCT, abs=0.5)
    at3 = level_forces_n(model, 3.0, levels)
    for ratio, force in data.ISSUE_FORCE_AT_3MM_N.items():
        assert at3[ratio] == pytest.approx(force, abs=1.0)
    assert levels_in_band(model, 3.0, levels, 500.0, 0.05) == []
    assert levels_in_band(model, 1.0, levels, 500.0, 0.05) == [1.4]


def test_feed_stop_is_a_lower_bound_for_any_feed() -> None:
    """Any feed >= 0 after the step leaves more force than none (the floor's premise)."""
    model = paper_model()
    t_s, floor = feed_stop_response(model, (1.0, 2.0), 500.0, dt_s=1e-3, duration_s=0.5)
    ratios = np.random.default_rng(0).uniform(0.0, 1.5, size=len(t_s))
    feed = FirstOrderLag(model.interpolator_tau_s, model.steady_ratio(500.0, 1.0) * 0.2)
    force = FirstOrderLag(model.chip_tau_s, 500.0)
    other = [force.step(1e-3, 1773.0 * 2.0 * feed.step(1e-3, r * 0.2)) for r in ratios]
    assert np.all(np.array(other) >= floor - 1e-9)


def test_segment_measures_on_a_known_trace() -> None:
    t = 1e-3 * np.arange(1, 8001)
    force = np.full_like(t, 500.0)
    after = t > 4.0
    force[after] = 500.0 + 200.0 * np.exp(-(t[after] - 4.0) / 0.1)       # +40 %, back within 25 N at 0.1 ln 8
    traces = Traces(t, force, np.ones_like(t), np.ones_like(t), np.where(after, 2.0, 1.0))
    first, second = segments(traces, DepthSchedule([[0.0, 1.0], [4.0, 2.0]]), 500.0, 0.05)
    assert first.overshoot_pct == pytest.approx(0.0) and first.depth_mm == 1.0
    assert second.depth_mm == 2.0
    assert second.overshoot_pct == pytest.approx(40.0 * np.exp(-0.01), abs=0.01)    # first sample after the step
    assert second.settling_s == pytest.approx(0.1 * np.log(8.0), abs=2e-3)


def test_no_feedback_law_beats_the_floor_and_smc_beats_adaptive() -> None:
    step = step_floor(paper_model(), (1.0, 2.0), data.REFERENCE_N, data.BAND_FRACTION)
    by_key = {c.key: c for c in MAIN_CASES}
    results = {k: run_case(by_key[k], duration_s=5.0) for k in ("smc/cont", "adaptive/cont", "smc/4bit")}
    for result in results.values():
        seg = result.segments[1]
        before = seg.before_n / data.REFERENCE_N
        assert seg.overshoot_pct >= 100.0 * ((1.0 + step.overshoot_pct / 100.0) * before - 1.0) - 0.5
    assert results["smc/cont"].segments[1].overshoot_pct < results["adaptive/cont"].segments[1].overshoot_pct


def test_smc_from_rest_with_the_switch_never_leaves_zero() -> None:
    result = run_case(REST_CASES[1], duration_s=1.0)
    assert result.traces.force_n.max() == 0.0 and result.traces.applied_ratio.max() == 0.0


def test_quick_bench_prints_and_writes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    options = argparse.Namespace(name="paper004", quick=True, json=tmp_path / "f.json", out=tmp_path / "out")
    assert BENCHES["paper004"](options) == 0
    text = capsys.readouterr().out
    assert "1. Floors from the model" in text and "5. Preview" in text
    assert {p.name for p in (tmp_path / "out").glob("fig_*.png")} >= {"fig_adaptive.png", "fig_smc.png"}
    figures = json.loads((tmp_path / "f.json").read_text())
    assert figures["floors"]["steps"]["1->2"]["overshoot_pct"] == pytest.approx(39.0, abs=0.5)
