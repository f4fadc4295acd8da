"""Bench ``jerk``: its figures on the zig-zag hold the limits and P and compare the three plans."""
from __future__ import annotations

from cnc_tools.bench.blending_corpus import zigzag
from cnc_tools.bench.jerk import program_figures


def test_zigzag_figures_keep_every_limit_and_pass_corners_at_speed() -> None:
    figures = program_figures(zigzag())
    assert max(figures["velocity_ratio"], figures["acceleration_ratio"], figures["jerk_ratio"]) <= 1.0 + 1e-9
    assert 0.5 < figures["deviation_over_p"] <= 1.0
    assert figures["corners_at_speed"] == figures["junctions"] == 29
    assert figures["jerk_s"] > figures["blended_s"] > 0.0   # a jerk limit costs time against the plan without it
    assert figures["exact_stop_s"] > 0.0
