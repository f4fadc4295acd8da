"""Tier 3: the turning run with the preview from the program's depth schedule, graph against engine.

The node builds the same plans from its ``preview.*`` parameters as the engine's stage from the scenario, so
the recorded override and force equal the engine's to 1e-9, and the depth step's overshoot is cut.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import load_scenario

pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parents[2]
TURNING = ROOT / "scenarios" / "paper004_turning.yaml"
STEPS = [[0.0, 1.0], [0.8, 2.0]]


def test_the_graph_applies_the_engines_preview_plans(tmp_path: Path) -> None:
    scenario = load_scenario(TURNING, {"duration_s": 1.5, "plant": {"cutting": {"depth_schedule": STEPS}},
                                       "force_regulator": {"preview": {"depth_schedule": STEPS}}})
    graph = run_scenario(scenario, "graph", tmp_path / "graph")
    engine = run_engine(scenario)
    assert graph.integrity.complete and graph.ticks == engine.ticks
    assert graph.feed_override is not None and engine.feed_override is not None
    assert graph.cutting_force is not None and engine.cutting_force is not None
    np.testing.assert_allclose(graph.feed_override.applied_ratio, engine.feed_override.applied_ratio,
                               rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(graph.cutting_force.force_n, engine.cutting_force.force_n, rtol=0.0, atol=1e-9)
    step = graph.cutting_force.stamp_ns >= 800_000_000
    assert graph.cutting_force.force_n[step, 0].max() < 1.1 * 500.0, "the plan held the step's overshoot"
