"""Shop G-code (G55 work offset, R arcs of both signs, G4 dwell, G64 P, M30) through the engine, scored."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_tools.analysis.scoring import score_run
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import load_scenario

SHOP = Path(__file__).resolve().parents[3] / "scenarios" / "gcode_shop.yaml"


@pytest.fixture(scope="module")
def run() -> RunRecord:
    return run_engine(load_scenario(SHOP))


def test_the_program_reads_with_its_lines_offsets_and_dwell(run: RunRecord) -> None:
    program = run.program
    assert [segment.source_line for segment in program.segments] == [4, 5, 6, 8, 9, 10]
    assert [(d.before_segment, d.duration_s, d.source_line) for d in program.dwells] == [(3, 0.25, 7)]
    assert program.path_tolerance_m == pytest.approx(1e-5)
    assert_allclose(program.segments[1].start_m, [0.005, 0.005])  # G55 X0 Y0 is machine X5 Y5
    assert_allclose(program.segments[2].center_m, [0.015, 0.010], atol=1e-12)  # R5 ccw: short way
    assert_allclose(program.segments[3].center_m, [0.025, 0.010], atol=1e-12)  # R-5 cw: long way
    assert program.segments[3].sweep_rad == pytest.approx(1.5 * np.pi)


def test_the_reference_holds_for_the_dwell_and_ends_at_m30(run: RunRecord) -> None:
    reference = run.reference
    assert reference is not None
    at_dwell = np.all(np.abs(reference.position_m - [0.020, 0.010]) < 1e-12, axis=1)
    still = at_dwell & np.all(reference.velocity_m_s == 0.0, axis=1)
    assert 0.25 - 0.01 <= np.count_nonzero(still) * 0.01 <= 0.25 + 0.02
    assert np.max(reference.position_m[:, 0]) == pytest.approx(0.030, abs=1e-5)  # the long arc's far side
    assert_allclose(reference.position_m[-1], [0.0, 0.0], atol=1e-12)  # N80, then M30


def test_the_run_is_complete_and_scored_against_the_program(run: RunRecord) -> None:
    reference = run.reference
    assert reference is not None and run.integrity.complete and run.summary["faults"] == []
    on_path, _ = run.program.contour_distance(reference.position_m)
    tolerance_m = run.program.path_tolerance_m or 0.0  # G64 P0.01: corners blended within 10 µm
    assert tolerance_m == pytest.approx(1e-5)
    assert 1e-7 < np.max(on_path) <= tolerance_m + 1e-9  # off the programmed path only at the blends
    score = score_run(run)
    assert len(score.segments) == len(run.program.segments) == 6
    assert sum(stats.n_samples for stats in score.segments) == score.contour.n_samples == run.ticks
    maximum_m = score.contour.values_si["max"]
    assert 0.0 < maximum_m < 1e-3  # PID on paper 000's drives: hundreds of µm at most
