"""The shipped turning scenario holds the force without a limit cycle through the 4-bit switch (tier 1, engine)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cnc_contour_control.force import ForceRegulator, ForceRegulatorConfig
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
TURNING = ROOT / "scenarios" / "paper004_turning.yaml"
#: 2 mm, then 3 mm (where no level lands: 40 % gives 426 N, 50 % 532 N) from 1.5 s; 6 s.
SHORT: dict[str, Any] = {"duration_s": 6.0, "plant": {"cutting": {"depth_schedule": [[0.0, 2.0], [1.5, 3.0]]}}}
#: The same run with the paper's SMC (η 1e5) and plain rounding.
PAPERS_LAW = ROOT / "scenarios" / "paper004_turning_smc.yaml"


def steady(run: RunRecord, start_s: float, end_s: float) -> tuple[float, float]:
    """Mean force [N] and applied-override changes per second over [start_s, end_s)."""
    assert run.cutting_force is not None and run.feed_override is not None
    t_s = run.cutting_force.stamp_ns * 1e-9
    inside = (t_s >= start_s) & (t_s < end_s)
    changes = np.count_nonzero(np.diff(run.feed_override.applied_ratio[inside]))
    return float(run.cutting_force.force_n[inside, 0].mean()), changes / (end_s - start_s)


@pytest.fixture(scope="module")
def shipped() -> RunRecord:
    return run_engine(load_scenario(TURNING, SHORT))


def test_where_a_level_lands_the_override_stays(shipped: RunRecord) -> None:
    mean_n, rate = steady(shipped, 0.8, 1.5)
    assert rate == 0.0 and abs(mean_n - 500.0) <= 25.0


def test_where_no_level_lands_the_mean_holds_with_few_changes(shipped: RunRecord) -> None:
    mean_n, rate = steady(shipped, 3.0, 6.0)
    assert rate <= 2.0, f"{rate} override changes per second"
    assert abs(mean_n - 500.0) <= 25.0, f"mean {mean_n} N"


def test_the_papers_law_in_the_same_run_bangs_the_switch() -> None:
    run = run_engine(load_scenario(PAPERS_LAW, SHORT))
    assert steady(run, 0.8, 1.5)[1] > 10.0 and steady(run, 3.0, 6.0)[1] > 10.0


def test_the_hysteresis_holds_the_level_but_not_a_plan() -> None:
    regulator = ForceRegulator(ForceRegulatorConfig(law="pi", hysteresis_fraction=0.25))
    regulator.reset(0.7)
    held = regulator.last.applied_ratio
    assert regulator._apply(0.77, planned=False) == held, "within 0.75 of a level: held"
    assert regulator._apply(0.78, planned=False) == pytest.approx(0.8)
    assert regulator._apply(0.76, planned=True) == pytest.approx(0.8), "a plan's level is applied as planned"
