"""Tier 3: paper 002 with a spindle step on the node graph: the servos redesign the PDC at the engine's tick.

The servos follow the spindle speed they command (``servo.follow_spindle``): MBDA+PDC, +10 % at 0.1 s. The Y
servo's own schedule also asks for 20000 rpm at 0.05 s, which no design takes: it keeps its design and reports
the refusal on ``/diagnostics`` (WARN), the run goes on. Positions and commands equal the engine's to 1e-9.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_tools.bagio.diagnostics import read_statuses
from cnc_tools.reproductions.paper002.runs import Case, scenario_for
from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.engine import run_engine, tick_count
from cnc_tools.runs.scenario import Scenario

pytestmark = pytest.mark.e2e

STEP = (0.1, 1650.0)


def spindle_step() -> Scenario:
    """0.25 s of the paper-002 circle, MBDA+PDC following the spindle; Y also asked for a speed it refuses."""
    base = scenario_for(Case("graph_step", "circle", "mbda_pdc", step=STEP, duration_s=0.25, follow=True))
    servo = dict(base.raw["servo"])
    servo["axes"] = {"y": {"law_params": {"model": "y"}, "spindle_schedule_t_s": [0.0, 0.05, STEP[0]],
                           "spindle_schedule_rpm": [1500.0, 20000.0, STEP[1]]}}
    return base.variant(servo=servo)


def test_the_graph_redesigns_at_the_engines_tick_and_reports_a_refused_speed(tmp_path: Path) -> None:
    scenario = spindle_step()
    graph = run_scenario(scenario, "graph", tmp_path / "graph")
    engine = run_engine(scenario)
    assert graph.integrity.complete and graph.ticks == engine.ticks == tick_count(scenario)
    assert engine.summary["spindle_redesigns"] == {"x": 1, "y": 1}
    assert [(r["axis"], r["stamp_ns"]) for r in engine.summary["spindle_refusals"]] == [("y", 50_000_000)]
    np.testing.assert_allclose(graph.joint_states.position_m, engine.joint_states.position_m, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(graph.command_array(), engine.command_array(), rtol=0.0, atol=1e-9)
    _, statuses = read_statuses(tmp_path / "graph" / "bag")
    refused = [s for s in statuses if s.level == 1 and "no design for spindle_rpm 20000" in s.message]
    assert len(refused) == 1 and refused[0].name.endswith("servo_y") and refused[0].values["stamp_ns"] == "50000000"
