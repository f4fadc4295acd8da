"""Tier 3: a blended program (path tolerance from the interpolator's parameter) on the node graph and the engine.

The bag's ``path`` carries the tolerance the interpolator node planned with, so the graph run's score sets
the reference's deviation beside it exactly as the engine run's does.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_tools.analysis.scoring import score_run
from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
SHOP = ROOT / "scenarios" / "gcode_shop.yaml"
TOLERANCE_MM = 0.005
#: Line-line and line-arc corners in G55 (machine X5 Y5); no G64: the interpolator's parameter blends them.
GCODE = """N10 G21 G90 G17
N20 G55 G0 X0 Y0
N30 G1 X4 F900
N40 G3 X6 Y2 R2
N50 G1 Y4
N60 G1 X0 Y0
N70 M30
"""
pytestmark = pytest.mark.e2e


def test_graph_and_engine_report_the_same_deviation_beside_the_tolerance(tmp_path: Path) -> None:
    shop = load_scenario(SHOP)  # its drives and PID; a shorter part, the tolerance from the node's parameter
    program = {**shop.raw["program"], "gcode": GCODE}
    scenario = shop.variant({"interpolator": {"path_tolerance_mm": TOLERANCE_MM}, "settle_s": 0.1}, program=program)
    graph = run_scenario(scenario, "graph", tmp_path / "graph")
    engine = run_scenario(scenario, "engine")
    assert graph.integrity.complete and graph.ticks == engine.ticks
    assert graph.program.path_tolerance_m == engine.program.path_tolerance_m == pytest.approx(TOLERANCE_MM * 1e-3)
    np.testing.assert_allclose(graph.reference.position_m, engine.reference.position_m, rtol=0.0, atol=1e-9)
    graph_score, engine_score = score_run(graph), score_run(engine)
    for deviation in (graph_score.deviation, engine_score.deviation):
        assert deviation is not None and 1e-7 < deviation.max_m <= TOLERANCE_MM * 1e-3 + 1e-9
    figures = [{k: v for k, v in score.deviation.to_dict().items() if k.endswith("_um")}
               for score in (graph_score, engine_score)]
    assert figures[0] == pytest.approx(figures[1], rel=0.0, abs=1e-6)  # µm: the references agree to 1e-9 m
    lines = [graph_score.deviation.lines(), engine_score.deviation.lines()]
    assert lines[0] == lines[1] and "path tolerance 5 µm" in lines[0][0]
    assert "not recorded" not in graph_score.to_table()
