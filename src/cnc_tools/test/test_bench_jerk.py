"""Bench ``jerk``: its figures on the 36-gon hold the limits and P and compare the plans."""
from __future__ import annotations

from cnc_tools.bench.blending_corpus import polygon
from cnc_tools.bench.jerk import program_figures


def test_polygon_figures_keep_every_limit_and_pass_corners_at_speed() -> None:
    figures = program_figures(polygon(36))
    assert max(figures["velocity_ratio"], figures["acceleration_ratio"], figures["jerk_ratio"]) <= 1.0 + 1e-9
    assert 0.5 < figures["deviation_over_p"] <= 1.0
    assert figures["corners_at_speed"] == figures["junctions"] == 35
    assert figures["jerk_s"] > figures["blended_s"] > 0.0   # a jerk limit costs time against the plan without it
    assert figures["exact_stop_s"] > 0.0 and figures["jerk_s"] < figures["jerk_exact_stop_s"]
