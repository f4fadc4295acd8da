"""``cnc-contour circular``: the diagnosis of a recorded cw/ccw circle pair, and its bad input."""
from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from cnc_tools.analysis.ballbar import BallbarDiagnosis, CircleTrace, diagnose_circles
from cnc_tools.analysis.ballbar_reversals import diagnose_reversals
from cnc_tools.bagio.record_bag import write_record_bag
from cnc_tools.bagio.synthetic import circle_program, circle_trajectory, corner_program, write_run_bag
from cnc_tools.cli.main import main
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import load_scenario

SCENARIO = Path(__file__).resolve().parents[3] / "scenarios" / "paper000_circle_high.yaml"


@dataclasses.dataclass(frozen=True)
class Pair:
    ccw_bag: Path
    cw_bag: Path
    ccw: RunRecord
    cw: RunRecord


@pytest.fixture(scope="module")
def pair(tmp_path_factory: pytest.TempPathFactory) -> Pair:
    """A ccw and a cw engine run of the paper-000 circle (full program, T = 10 ms), written to bags."""
    folder = tmp_path_factory.mktemp("circular")
    scenario = load_scenario(SCENARIO)
    assert scenario.sample_time_s == pytest.approx(0.01)
    ccw = run_engine(scenario.variant({"program": {"direction": "ccw"}}))
    cw = run_engine(scenario.variant({"program": {"direction": "cw"}}))
    return Pair(write_record_bag(ccw, folder / "ccw"), write_record_bag(cw, folder / "cw"), ccw, cw)


def _direct_trace(record: RunRecord, direction: str) -> CircleTrace:
    """The trace built by hand: engine samples while the reference is not done (same stamps on both topics)."""
    assert np.array_equal(record.joint_states.stamp_ns, record.reference.stamp_ns)
    moving = ~record.reference.done
    arc = record.program.segments[0]
    a, b = arc.plane
    return CircleTrace(record.joint_states.position_m[moving][:, [a, b]], (arc.center_m[a], arc.center_m[b]),
                       arc.radius_m, direction, arc.feed_m_s)


def _table_values(out: str) -> dict[str, str]:
    values = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 3 and parts[0].endswith(("_um", "_s", "_urad", "_ppm")):
            values[parts[0]] = parts[1]
    return values


def _assert_table_matches(out: str, expected: BallbarDiagnosis) -> None:
    values = _table_values(out)
    scalars = [f.name for f in dataclasses.fields(expected) if f.name not in ("traces", "skipped", "cyclic_error_um")]
    for name in scalars:
        value = getattr(expected, name)
        if value is None:
            assert values[name] == "skipped"
        else:
            assert float(values[name]) == pytest.approx(value, rel=1e-5, abs=1e-9), name
    for k, value in zip(range(3, 11), expected.cyclic_error_um):
        assert float(values[f"cyclic_error_h{k}_um"]) == pytest.approx(value, rel=1e-5, abs=1e-9)
    for trace in expected.traces:
        assert float(values[f"{trace.direction}.ellipse_45_um"]) == pytest.approx(trace.ellipse_45_um, rel=1e-5)


def _assert_json_matches(written: object, expected: object) -> None:
    if isinstance(expected, dict):
        assert set(written) == set(expected)
        for key in expected:
            _assert_json_matches(written[key], expected[key])
    elif isinstance(expected, (list, tuple)):
        assert len(written) == len(expected)
        for w, e in zip(written, expected):
            _assert_json_matches(w, e)
    elif isinstance(expected, float):
        assert written == pytest.approx(expected, rel=1e-12, abs=1e-12)
    else:
        assert written == expected


@pytest.mark.parametrize("order", [("cw", "ccw"), ("ccw", "cw")])
def test_pair_table_and_json_hold_the_direct_diagnosis(pair: Pair, tmp_path: Path, order: tuple[str, str],
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    bags = {"ccw": pair.ccw_bag, "cw": pair.cw_bag}
    records = {"ccw": pair.ccw, "cw": pair.cw}
    expected = diagnose_circles([_direct_trace(records[d], d) for d in order])
    assert expected.skipped == () and expected.servo_mismatch_um is not None
    out_json = tmp_path / "diag.json"
    assert main(["circular", *(str(bags[d]) for d in order), "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "not done" in out  # the sample rule is said
    _assert_table_matches(out, expected)
    written = json.loads(out_json.read_text())
    _assert_json_matches(written["diagnosis"], dataclasses.asdict(expected))
    assert [t["direction"] for t in written["traces"]] == list(order)
    assert all(t["n_samples"] == int((~records[t["direction"]].reference.done).sum()) for t in written["traces"])


def test_reversal_rows_and_plot(pair: Pair, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    expected = diagnose_reversals([_direct_trace(pair.ccw, "ccw"), _direct_trace(pair.cw, "cw")])
    plot, out_json = tmp_path / "plots" / "circle.png", tmp_path / "diag.json"
    assert main(["circular", str(pair.ccw_bag), str(pair.cw_bag), "--plot", str(plot), "--json", str(out_json)]) == 0
    values = _table_values(capsys.readouterr().out)
    for name in ("spike_x_um", "spike_y_um", "backlash_x_um", "backlash_y_um"):
        assert float(values[name]) == pytest.approx(getattr(expected, name), rel=1e-5, abs=1e-9), name
    assert len(expected.reversals) == 8
    for r in expected.reversals:
        assert float(values[f"{r.direction}.{r.axis}{r.angle_deg:g}.step_um"]) == pytest.approx(r.step_um, rel=1e-5,
                                                                                                 abs=1e-9)
    _assert_json_matches(json.loads(out_json.read_text())["reversals"], dataclasses.asdict(expected))
    data = plot.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000


def test_one_bag_skips_the_diagnoses_that_need_both_directions(pair: Pair,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    expected = diagnose_circles([_direct_trace(pair.cw, "cw")])
    assert main(["circular", str(pair.cw_bag)]) == 0
    out = capsys.readouterr().out
    _assert_table_matches(out, expected)
    for name in ("servo_mismatch_um", "gain_difference_s", "squareness_urad"):
        assert f"skipped: {name}: needs both cw and ccw traces" in out


def _error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 1
    captured = capsys.readouterr()
    errors = [line for line in captured.err.splitlines() if "error:" in line]
    assert len(errors) == 1, captured.err
    assert captured.out == ""
    return errors[0]


def test_same_direction_twice_is_an_error(pair: Pair, capsys: pytest.CaptureFixture[str]) -> None:
    line = _error(capsys, ["circular", str(pair.ccw_bag), str(pair.ccw_bag)])
    assert str(pair.ccw_bag) in line and "both run ccw" in line


def test_different_circles_are_an_error(pair: Pair, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    other = write_run_bag(tmp_path / "small", circle_program(radius_m=0.01, clockwise=True),
                          circle_trajectory(0.01, 0.0, n=200), commands=False)
    line = _error(capsys, ["circular", str(pair.ccw_bag), str(other)])
    assert str(other) in line and "different circle" in line and "0.01" in line


def test_program_without_a_circle_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_run_bag(tmp_path / "corner", corner_program(), circle_trajectory(0.01, 0.0, n=50), commands=False)
    line = _error(capsys, ["circular", str(bag)])
    assert str(bag) in line and "not one circle" in line


def test_truncated_and_missing_bags_are_errors(pair: Pair, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    damaged = tmp_path / "damaged"
    shutil.copytree(pair.ccw_bag, damaged)
    mcap = next(damaged.glob("*.mcap"))
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])
    line = _error(capsys, ["circular", str(damaged), str(pair.cw_bag)])
    assert str(damaged) in line
    missing = tmp_path / "nowhere"
    line = _error(capsys, ["circular", str(missing)])
    assert str(missing) in line
    line = _error(capsys, ["circular", str(pair.ccw_bag), str(pair.cw_bag), str(pair.cw_bag)])
    assert "1 or 2 bags" in line and "got 3" in line
