"""Scoring: the exact contour error, per-segment and per-axis metrics, units and renderings."""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.geometry import LineSegment, Program
from cnc_tools.analysis.metrics import METRICS, trapezoid_weights_s
from cnc_tools.analysis.scoring import score_run, tracking_errors
from cnc_tools.bagio.bag import BagIntegrity, BagWriter, read_bag
from cnc_tools.bagio.typestore import message_layout, project_typestore

R_M = 0.02


@pytest.mark.parametrize("offset_m", [5e-6, -3e-6, 1e-7, 2.5e-4])
def test_circle_with_a_radial_offset_has_exactly_that_contour_error(synth, offset_m: float) -> None:
    traj = synth.circle_trajectory(R_M, offset_m, n=3000)
    score = score_run(synth.make_run(synth.circle_program(radius_m=R_M), traj))
    assert_allclose(score.series.error_m, abs(offset_m), rtol=0, atol=1e-13)
    values = score.contour.values_si
    assert_allclose([values["max"], values["rms"], values["mean_abs"]], abs(offset_m), rtol=1e-9)
    duration_s = (traj.stamp_ns[-1] - traj.stamp_ns[0]) * 1e-9
    assert_allclose(values["ise"], offset_m**2 * duration_s, rtol=1e-9)


def test_line_with_a_known_normal_offset(synth) -> None:
    line = LineSegment(start_m=np.array([0.0, 0.0]), end_m=np.array([0.05, 0.02]), feed_m_s=0.01)
    program = Program(name="line", axis_names=("x", "y"), segments=(line,))
    traj = synth.offset_trajectory(program, [7e-6])
    score = score_run(synth.make_run(program, traj))
    assert_allclose(score.series.error_m, 7e-6, rtol=0, atol=1e-15)
    assert score.circular is None
    assert_allclose(score.series.path_length_m, np.linspace(0, line.length_m, 202)[1:-1], atol=1e-12)


def test_corner_points_take_the_nearest_of_both_segments(synth) -> None:
    program = synth.corner_program(side_m=0.01)
    points = np.array([[0.010 + 3e-6, -4e-6],     # beyond the corner: distance to the corner point
                       [0.010 - 2e-6, 5e-6],      # inside: 2 µm from the second line, 5 µm from the first
                       [0.010 - 6e-6, 1e-6]])     # inside: 1 µm from the first line
    distance, index = program.contour_distance(points)
    assert_allclose(distance, [5e-6, 2e-6, 1e-6], rtol=1e-9)
    assert_array_equal(index, [0, 1, 0])


def test_per_segment_metrics_and_their_sum(synth) -> None:
    program = synth.corner_program(side_m=0.01)
    score = score_run(synth.make_run(program, synth.offset_trajectory(program, [2e-6, -7e-6], n_per_segment=300)))
    first, second = score.segments
    assert (first.label, second.label) == ("0 line", "1 line")
    assert (first.n_samples, second.n_samples) == (300, 300)
    assert_allclose([first.values_si["max"], second.values_si["max"]], [2e-6, 7e-6], rtol=1e-9)
    assert_allclose(score.contour.values_si["max"], 7e-6, rtol=1e-9)
    assert_allclose(first.values_si["ise"] + second.values_si["ise"], score.contour.values_si["ise"], rtol=1e-12)
    assert_allclose(score.contour.values_si["mean_abs"], 4.5e-6, rtol=1e-9)


@pytest.mark.parametrize(("blu_m", "per_blu"), [(1e-5, 10.0), (1e-6, 1.0), (2.5e-6, 2.5)])
def test_blu_and_micrometre_columns(synth, blu_m: float, per_blu: float) -> None:
    score = score_run(synth.make_run(synth.circle_program(), synth.circle_trajectory(R_M, 4e-6)), blu_m=blu_m)
    data = score.to_dict()["contour_error"]
    assert_allclose(data["max_um"], 4.0, rtol=1e-9)
    assert_allclose(data["max_blu"], 4.0 / per_blu, rtol=1e-9)
    assert_allclose(data["ise_blu2_s"], data["ise_um2_s"] / per_blu**2, rtol=1e-12)


def test_samples_before_the_first_reference_are_left_out_and_said_so(synth) -> None:
    traj = synth.circle_trajectory(R_M, 1e-6, n=500)
    traj.position_m[:20] += 1e-3  # a big error before the reference starts: must not be scored
    score = score_run(synth.make_run(synth.circle_program(), traj, reference_from=20))
    assert (score.window.n_recorded, score.window.n_scored, score.window.n_before_start) == (500, 480, 20)
    assert_allclose(score.contour.values_si["max"], 1e-6, rtol=1e-9)
    assert "20 samples before it not scored" in score.to_table()
    assert score.to_dict()["scored_samples"]["n_before_start"] == 20


def test_tracking_error_is_reference_minus_position_at_shared_stamps(synth) -> None:
    traj = synth.circle_trajectory(R_M, 0.0, n=400)
    traj.position_m[:, 0] -= 3e-6
    traj.position_m[:, 1] += 1e-6
    run = synth.make_run(synth.circle_program(), traj, reference_from=100)
    stamps, error = tracking_errors(run)
    assert_array_equal(stamps, traj.stamp_ns[100:])
    assert_allclose(error, np.tile([3e-6, -1e-6], (300, 1)), atol=1e-15)
    score = score_run(run)
    x, y = score.tracking
    assert (x.label, x.n_samples) == ("x", 300)
    assert_allclose([x.values_si["max"], x.values_si["rms"], y.values_si["max"]], [3e-6, 3e-6, 1e-6], rtol=1e-9)


def test_metric_registry_choice_and_unknown_names(synth) -> None:
    run = synth.make_run(synth.circle_program(), synth.circle_trajectory(R_M, 1e-6, n=100))
    score = score_run(run, metrics=["rms"])
    assert list(score.contour.values_si) == ["rms"]
    with pytest.raises(ConfigError, match=r"must be one of \['ise', 'max', 'mean_abs', 'rms'\], got 'p99'"):
        score_run(run, metrics=["p99"])
    assert set(METRICS) == {"max", "rms", "mean_abs", "ise"}


def test_trapezoid_weights_integrate_exactly() -> None:
    t = np.array([0.0, 0.1, 0.3, 0.6])
    weights = trapezoid_weights_s(t)
    assert_allclose(weights, [0.05, 0.15, 0.25, 0.15])
    assert_allclose(np.sum((2 * t + 1) * weights), np.trapezoid(2 * t + 1, t))


def test_renderings_table_json_csv(synth) -> None:
    program = synth.corner_program()
    traj = synth.offset_trajectory(program, [2e-6, 3e-6], n_per_segment=50)
    traj.position_m[50:] = traj.position_m[49]  # everything on the first segment: the second has no samples
    score = score_run(synth.make_run(program, traj, name="corner_run"))
    data = json.loads(score.to_json())
    assert data["segments"][1]["n_samples"] == 0 and data["segments"][1]["max_um"] is None
    assert data["integrity"]["complete"] is True and data["run"] == "corner_run"
    rows = list(csv.DictReader(io.StringIO(score.to_csv())))
    assert {r["unit"] for r in rows} == {"um", "blu", "um2_s", "blu2_s"}
    assert any(r["scope"] == "segment" and r["item"] == "0 line" and r["metric"] == "max" for r in rows)
    table = score.to_table().splitlines()
    block = table[table.index(next(line for line in table if line.strip().startswith("contour error  "))):][:6]
    assert len({len(line) for line in block}) == 1, "contour table columns are not aligned"
    assert any(line.strip().startswith("1 line") and line.rstrip().endswith("-") for line in block)


def test_an_incomplete_bag_says_so_in_every_output(synth) -> None:
    integrity = BagIntegrity(False, "scan", {"/cnc/joint_states": 10}, None, "unknown",
                             ("the file ends inside a chunk",))
    run = synth.make_run(synth.circle_program(), synth.circle_trajectory(R_M, 0.0, n=10), integrity=integrity)
    score = score_run(run)
    assert "INCOMPLETE" in score.to_table() and "unknown" in score.to_table()
    assert json.loads(score.to_json())["integrity"]["lost"] is None


def test_scoring_a_bag_end_to_end(circle_bag: Path) -> None:
    score = score_run(read_bag(circle_bag))
    assert_allclose(score.contour.values_si["max"], 5e-6, rtol=1e-9)
    assert score.window.n_scored == 2000


# --------------------------------------------------------------------------- speed: 60 s at 1 kHz, 3 axes
def _rows(message: object, msgtype: str, columns: dict[str, np.ndarray]) -> np.ndarray:
    """(N, L) uint8 CDR messages: ``message`` serialised once, its numeric fields replaced per row."""
    store = project_typestore()
    template = bytes(store.serialize_cdr(message, msgtype))
    layout = message_layout(template, msgtype, store)
    n = len(next(iter(columns.values())))
    matrix = np.tile(np.frombuffer(template, np.uint8), (n, 1))
    for path, values in columns.items():
        start, count, dtype, _ = layout.numbers[path]
        matrix[:, start:start + dtype.itemsize * count] = \
            np.ascontiguousarray(values, dtype=dtype).reshape(n, count).view(np.uint8)
    return matrix


def _big_bag(path: Path, synth, seconds: int = 60, rate_hz: int = 1000) -> Path:
    n, axes = seconds * rate_hz, ["x", "y", "z"]
    program = synth.circle_program(n_axes=3)
    traj = synth.circle_trajectory(R_M, 3e-6, n=n, n_axes=3, dt_s=1.0 / rate_hz)
    sec, nanosec = traj.stamp_ns // 1_000_000_000, traj.stamp_ns % 1_000_000_000
    stamp = {"header.stamp.sec": sec, "header.stamp.nanosec": nanosec}
    zero = np.zeros(3)
    rows = {
        "/cnc/joint_states": _rows(synth.joint_state(0, axes, zero, zero), "sensor_msgs/msg/JointState",
                                   {**stamp, "position": traj.position_m, "velocity": traj.reference_velocity_m_s}),
        "/cnc/reference": _rows(synth.reference(0, axes, zero, zero), "cnc_contour_interfaces/msg/Reference",
                                {**stamp, "position_m": traj.reference_m, "velocity_m_s": traj.reference_velocity_m_s}),
        **{f"/cnc/servo/{a}/command": _rows(synth.axis_command(0, a, 0.0, 0.0), synth.COMMAND_TYPE,
                                            {**stamp, "error_m": traj.reference_m[:, k] - traj.position_m[:, k]})
           for k, a in enumerate(axes)},
    }
    topics = {**synth.TOPICS, **{t: synth.COMMAND_TYPE for t in rows if "servo" in t}}
    topics.pop("/clock")
    with BagWriter(path, topics) as writer:
        writer.write_message("/cnc/path", 0, synth.path_message(program))
        for k, stamp_ns in enumerate(traj.stamp_ns.tolist()):
            for topic, matrix in rows.items():
                writer.write(topic, stamp_ns, matrix[k].tobytes())
    return path


def test_a_60s_1khz_3_axis_run_is_scored_completely(tmp_path: Path, synth) -> None:
    """Every sample of a long run is scored (its speed is measured by ``cnc-contour bench scoring``)."""
    bag = _big_bag(tmp_path / "big", synth)
    score = score_run(read_bag(bag, commands=False))
    assert score.window.n_scored == 60_000
    assert_allclose(score.contour.values_si["max"], 3e-6, rtol=1e-6)
