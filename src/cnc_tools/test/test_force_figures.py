"""The force table of a run: every sample in exactly one depth segment, peaks from every sample (tier 1)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from cnc_tools.analysis.force import STEP_WINDOW_S, force_figures
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
TURNING = ROOT / "scenarios" / "paper004_turning.yaml"


@pytest.fixture(scope="module")
def run() -> RunRecord:
    return run_engine(load_scenario(TURNING, {"duration_s": 1.0, "plant": {"cutting": {
        "depth_schedule": [[0.0, 1.0], [0.5, 2.0]]}}}))


def with_schedule(run: RunRecord, rows: list[list[float]]) -> RunRecord:
    """``run`` as if its plant had drawn ``rows`` (the table reads the schedule from the summary)."""
    summary = dict(run.summary)
    summary["plant"] = {**summary["plant"], "cutting": {**summary["plant"]["cutting"], "depth_schedule": rows}}
    return dataclasses.replace(run, summary=summary)


def test_a_segment_of_one_sample_keeps_its_peak(run: RunRecord) -> None:
    assert run.cutting_force is not None
    t_s, force_n = run.cutting_force.stamp_ns * 1e-9, run.cutting_force.force_n[:, 0]
    k = int(np.argmax(force_n))
    assert 0 < k < len(t_s) - 1
    rows = [[0.0, 1.0], [float(t_s[k]) - 1e-6, 2.0], [float(t_s[k]) + 1e-6, 2.0]]
    figures = force_figures(with_schedule(run, rows), 500.0)
    assert figures is not None and len(figures.segments) == 3
    assert figures.segments[1].peak_n == force_n[k], "the one-sample segment is a row with its sample's force"
    assert max(s.peak_n for s in figures.segments) == force_n.max()


def test_samples_before_the_first_schedule_time_are_in_the_first_segment(run: RunRecord) -> None:
    assert run.cutting_force is not None
    force_n = run.cutting_force.force_n[:, 0]
    figures = force_figures(with_schedule(run, [[0.3, 1.0], [0.5, 2.0]]), 500.0)
    assert figures is not None and figures.segments[0].start_s == 0.0
    assert max(s.peak_n for s in figures.segments) == force_n.max()


def test_the_step_overshoot_reads_the_first_half_second_of_a_segment(run: RunRecord) -> None:
    assert run.cutting_force is not None
    t_s, force_n = run.cutting_force.stamp_ns * 1e-9, run.cutting_force.force_n[:, 0]
    figures = force_figures(with_schedule(run, [[0.0, 1.0], [0.2, 1.0], [0.5, 2.0]]), 500.0)
    assert figures is not None
    for segment, start_s, end_s in zip(figures.segments, (0.0, 0.2, 0.5), (0.2, 0.5, 1.0)):
        inside = (t_s >= start_s - 1e-9) & (t_s < min(start_s + STEP_WINDOW_S, end_s) - 1e-9)
        assert segment.step_overshoot_pct == pytest.approx(100.0 * (force_n[inside].max() / 500.0 - 1.0))
