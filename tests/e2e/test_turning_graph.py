"""Tier 3: the turning run (interpolator, two servos, plant, force regulator, recorder) against the engine.

The force loop closes over DDS: the plant's ``cutting_force(k)`` -> the regulator's ``feed_override(k)`` -> the
interpolator's ``reference(k+1)``. The recorded force, override and reference equal the engine's to 1e-9.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.engine import run_engine, tick_count
from cnc_tools.runs.scenario import Scenario, load_scenario

pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parents[2]
TURNING = ROOT / "scenarios" / "paper004_turning.yaml"


def short_turning() -> Scenario:
    """The paper-004 scenario cut to 1.5 s with one depth step, 1 -> 2 mm at 0.8 s."""
    return load_scenario(TURNING, {"duration_s": 1.5, "plant": {"cutting": {"depth_schedule": [[0.0, 1.0],
                                                                                                [0.8, 2.0]]}}})


def test_the_turning_graph_records_the_engines_force_loop(tmp_path: Path) -> None:
    scenario = short_turning()
    assert scenario.pipeline().names == ("plant", "interpolator", "servo", "force_regulator")
    graph = run_scenario(scenario, "graph", tmp_path / "graph")
    engine = run_engine(scenario)
    assert graph.integrity.complete and graph.ticks == engine.ticks == tick_count(scenario)
    assert graph.cutting_force is not None and engine.cutting_force is not None
    assert graph.feed_override is not None and engine.feed_override is not None
    assert graph.reference is not None and engine.reference is not None
    np.testing.assert_array_equal(graph.cutting_force.stamp_ns, engine.cutting_force.stamp_ns)
    np.testing.assert_allclose(graph.cutting_force.force_n, engine.cutting_force.force_n, rtol=0.0, atol=1e-9)
    np.testing.assert_array_equal(graph.feed_override.stamp_ns, engine.feed_override.stamp_ns)
    for name in ("requested_ratio", "applied_ratio"):
        np.testing.assert_allclose(getattr(graph.feed_override, name), getattr(engine.feed_override, name),
                                   rtol=0.0, atol=1e-9, err_msg=name)
    for name in ("position_m", "velocity_m_s", "feed_override_ratio"):
        np.testing.assert_allclose(getattr(graph.reference, name), getattr(engine.reference, name),
                                   rtol=0.0, atol=1e-9, err_msg=name)
    np.testing.assert_allclose(graph.joint_states.position_m, engine.joint_states.position_m, rtol=0.0, atol=1e-9)
    force = graph.cutting_force.force_n[:, 0]
    assert force.max() > 400.0, "the tool cut"
    assert len(np.unique(graph.feed_override.applied_ratio)) > 2, "the regulator moved the override"
    step = graph.cutting_force.stamp_ns >= 800_000_000
    assert force[step].max() > force[~step].max(), "the depth step raised the force"
