"""The six-node graph (interpolator, two servos, estimator, compensator, plant) and the recorder, against the engine."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_tools.bagio.bag import read_bag
from cnc_tools.runs.engine import run_engine, tick_count
from cnc_tools.runs.graph import run_graph
from cnc_tools.runs.scenario import Scenario, load_scenario

pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parents[2]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"


def _learning(tmp: Path, name: str, method: str = "neural") -> Scenario:
    """The circle at 1 ms for 0.6 s with the window estimator and a learning compensator saving its state."""
    return load_scenario(CIRCLE, {"sample_time_s": 0.001, "duration_s": 0.6,
                                  "estimator": {"method": "window"},
                                  "compensator": {"method": method, "state_out": str(tmp / f"{name}.npz")}})


def test_six_node_graph_equals_the_engine_and_saves_the_same_learned_state(tmp_path: Path) -> None:
    graph_scenario = _learning(tmp_path, "graph")
    result = run_graph(graph_scenario, tmp_path / "run", record=True)
    assert result.faults == []
    recorded = read_bag(result.bag_path, namespace=result.namespace)
    engine = run_engine(_learning(tmp_path, "engine"))
    expected = tick_count(graph_scenario)
    assert recorded.ticks == engine.ticks == expected
    np.testing.assert_allclose(recorded.joint_states.position_m, engine.joint_states.position_m, rtol=0, atol=1e-9)
    for series in ("contour_error", "compensation"):
        assert getattr(recorded, series) is not None and getattr(engine, series) is not None, series
    np.testing.assert_allclose(recorded.contour_error.contour_error_m, engine.contour_error.contour_error_m,
                               rtol=0, atol=1e-9)
    np.testing.assert_allclose(recorded.compensation.correction, engine.compensation.correction, rtol=0, atol=1e-9)
    assert np.abs(engine.compensation.correction).max() > 0, "the compensator acted"
    for axis in graph_scenario.axes:
        np.testing.assert_allclose(recorded.commands[axis].compensation, engine.commands[axis].compensation,
                                   rtol=0, atol=1e-9)
    graph_state, engine_state = np.load(tmp_path / "graph.npz"), np.load(tmp_path / "engine.npz")
    assert sorted(graph_state.files) == sorted(engine_state.files)
    for key in graph_state.files:
        np.testing.assert_allclose(graph_state[key], engine_state[key], rtol=0, atol=1e-9, err_msg=key)
