"""Bench ``jerk``: both modes' figures, and the quicker that ``quickest`` runs, on a 120-gon hold the limits and P;
the FIR mode's override sweep too."""
from __future__ import annotations

from cnc_tools.bench.blending_corpus import polygon
from cnc_tools.bench.jerk import goals, program_figures, sweep_figures


def test_polygon_figures_keep_every_limit_and_p_in_both_modes() -> None:
    figures = program_figures(polygon(120, radius_m=0.005), spacing_m=1e-3)
    for mode in ("fir", "scurve"):
        met = goals(figures, mode)
        assert met["limits"] and met["P"], (mode, figures[mode])
    fir = figures["fir"]
    assert fir["filter"] is not None and fir["filter"]["taps"] == 50   # 2 * 250 mm/s^2 / (10 m/s^3 * 1 ms)
    assert figures["toppra_s"] < figures["blended_s"] < fir["cycle_s"] < figures["scurve"]["cycle_s"]
    assert fir["jerk_ratio"] > 0.4   # the jerk limit is what the filter's length is chosen for
    quickest = figures["quickest"]
    assert quickest["mode_used"] == "fir" and quickest["cycle_s"] == fir["cycle_s"], "the quicker mode ran"
    assert goals(figures, "quickest")["limits"] and goals(figures, "quickest")["P"]


def test_override_changes_mid_path_come_out_jerk_limited() -> None:
    figures = sweep_figures(polygon(36, radius_m=0.005), "changes mid-path")
    assert max(figures["velocity_ratio"], figures["acceleration_ratio"], figures["jerk_ratio"]) <= 1.0 + 1e-9
    assert figures["deviation_over_p"] <= 1.0 + 1e-9 and figures["jerk_ratio"] > 0.5
