"""Tier 3: the milling run (interpolator, two servos, plant with the milling process, force regulator, recorder)
against the engine: force, override and positions equal to 1e-9."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import load_scenario

pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parents[2]
MILLING = ROOT / "scenarios" / "paper004_milling.yaml"


def test_the_milling_graph_records_the_engines_force_loop(tmp_path: Path) -> None:
    scenario = load_scenario(MILLING, {"duration_s": 1.5, "plant": {"cutting": {"depth_schedule": [[0.0, 1.0],
                                                                                                 [0.8, 2.0]]}}})
    graph = run_scenario(scenario, "graph", tmp_path / "graph")
    engine = run_engine(scenario)
    assert graph.integrity.complete and graph.ticks == engine.ticks
    assert graph.cutting_force is not None and engine.cutting_force is not None
    assert graph.feed_override is not None and engine.feed_override is not None
    np.testing.assert_allclose(graph.cutting_force.force_n, engine.cutting_force.force_n, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(graph.feed_override.applied_ratio, engine.feed_override.applied_ratio,
                               rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(graph.joint_states.position_m, engine.joint_states.position_m, rtol=0.0, atol=1e-9)
    assert graph.summary["plant"]["cutting"]["model"] == "milling"
    assert graph.cutting_force.force_n[:, 0].max() > 150.0, "the mill cut"
