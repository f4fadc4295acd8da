"""Tier 3: a managed graph (lifecycle nodes driven by the lifecycle manager) runs the engine's run."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.graph import run_graph
from cnc_tools.runs.outputs import judge_bag
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.e2e


def test_a_managed_run_is_configured_and_activated_by_the_manager_and_equals_the_engine(tmp_path: Path) -> None:
    scenario = load_scenario(ROOT / "scenarios" / "paper000_circle_high.yaml", {"duration_s": 1.0})
    result = run_graph(scenario, tmp_path, record=True, managed=True)
    assert result.faults == [] and "lifecycle_manager" in result.exit_codes, result.exit_codes
    record, verdict = judge_bag(result.bag_path)
    assert verdict.complete, verdict.describe()
    engine = run_engine(scenario)
    np.testing.assert_allclose(record.joint_states.position_m, engine.joint_states.position_m, rtol=0, atol=1e-9)
    log = (tmp_path / "lifecycle_manager.log").read_text()
    order = [line.split("]: ")[-1] for line in log.splitlines() if line.endswith(": done")]
    assert order == [f"{t} {n}: done" for t in ("configure", "activate")
                     for n in ("interpolator", "servo_x", "servo_y", "plant")], log[-2000:]
