"""Tier 3: a plant with machine faults publishes tool_position; the graph's recorded tool position is the engine's."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.engine import run_engine, tick_count
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
FAULTS = {"squareness_urad": 150.0, "axes": {"x": {"backlash_um": 12.0, "scale_ppm": 80.0},
                                              "y": {"cyclic_amplitude_um": 2.0, "cyclic_pitch_mm": 5.0}}}
pytestmark = pytest.mark.e2e


def test_faulted_run_records_the_engines_tool_position(tmp_path: Path) -> None:
    # and a gain mismatch: y's own kp (servo.axes.y, merged over servo.law_params) reaches its servo node
    scenario = load_scenario(CIRCLE, {"duration_s": 2.0, "plant": {"faults": FAULTS},
                                      "servo": {"axes": {"y": {"law_params": {"kp": 3.0}}}}})
    assert [s.law_params["kp"] for s in scenario.servos] == [2.4, 3.0]
    graph = run_scenario(scenario, "graph", tmp_path / "graph")
    engine = run_engine(scenario)
    assert graph.integrity.complete and graph.ticks == tick_count(scenario) == engine.ticks
    assert graph.tool_position is not None and engine.tool_position is not None
    np.testing.assert_array_equal(graph.tool_position.stamp_ns, engine.tool_position.stamp_ns)
    np.testing.assert_allclose(graph.tool_position.position_m, engine.tool_position.position_m, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(graph.joint_states.position_m, engine.joint_states.position_m, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(graph.command_array(), engine.command_array(), rtol=0.0, atol=1e-9)
    # the faults act on the tool side only: the backlash (12 µm band) shows between motor and tool
    gap_um = np.abs(graph.tool_position.position_m - graph.joint_states.position_m).max(axis=0) * 1e6
    assert gap_um[0] > 5.0
