"""Tier 3: paper 002 with f_d estimated on line (``track_fd``) on the node graph: the servos' PDC redesigns for
the plant's spindle, 7 % slow, without a schedule, at the engine's ticks: positions and commands equal the
engine's to 1e-9, and differ from the same run without the estimate (so the redesign happened in both)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_tools.reproductions.paper002.runs import Case, scenario_for
from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.engine import run_engine

pytestmark = pytest.mark.e2e

#: Long enough for the estimate to settle (0.15 s) and leave the design's hysteresis.
DURATION_S = 0.25


def test_the_graph_tracks_f_d_as_the_engine_does(tmp_path: Path) -> None:
    slow = 1500.0 * 0.93
    tracked = scenario_for(Case("graph_tracked", "circle", "mbda_pdc", plant_rpm=slow, duration_s=DURATION_S,
                                track=True))
    graph = run_scenario(tracked, "graph", tmp_path / "graph")
    engine = run_engine(tracked)
    fixed = run_engine(scenario_for(Case("graph_fixed", "circle", "mbda_pdc", plant_rpm=slow,
                                         duration_s=DURATION_S)))
    assert graph.integrity.complete and graph.ticks == engine.ticks
    np.testing.assert_allclose(graph.joint_states.position_m, engine.joint_states.position_m, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(graph.command_array(), engine.command_array(), rtol=0.0, atol=1e-9)
    assert np.max(np.abs(engine.command_array() - fixed.command_array())) > 1e-6
