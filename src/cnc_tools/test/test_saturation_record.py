"""The ``saturated`` flag: set whenever the applied command is at the limit, in the engine record and a bag."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_contour_control.axis.servo import ServoConfig, ServoController, at_limit
from cnc_tools.bagio.bag import read_bag
from cnc_tools.bagio.record_bag import write_record_bag
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
#: Paper 000's line with the feed raised to 1900 mm/min: the PID clamps itself at 127 DAC on x.
LINE_FAST = {"duration_s": 1.0, "program": {"feed_mm_min": 1900}}


@pytest.fixture(scope="module")
def fast_line() -> RunRecord:
    return run_engine(load_scenario(ROOT / "scenarios" / "paper000_line_high.yaml", LINE_FAST))


@pytest.mark.parametrize(("total", "command", "expected"), [
    (127.0, 127.0, True),      # the law clamped itself exactly at the limit
    (-127.0, -127.0, True),
    (300.0, 127.0, True),      # the servo clipped
    (126.6, 127.0, True),      # rounding reached the limit
    (126.4, 126.0, False),
    (127.4, 126.0, True),      # limit not a multiple of the quantum: stepped back, still clamped
    (0.0, 0.0, False),
])
def test_at_limit(total: float, command: float, expected: bool) -> None:
    assert at_limit(total, command, 127.0) is expected


def test_a_self_clamping_pid_at_the_limit_is_flagged() -> None:
    servo = ServoController(ServoConfig(axis_name="x", law="pid", law_params={"kp": 2.4, "ki": 0.0, "kd": 0.0}))
    out = servo.step(0.01, 1.0e-3, 0.0, 0.0, 0.0, 0.0, 0.0)  # 100 BLU of error: 240 DAC before the law's clamp
    assert out.feedback == 127.0 and out.command == 127.0
    assert out.saturated


def test_engine_record_flags_every_sample_at_the_limit(fast_line: RunRecord) -> None:
    series = fast_line.commands["x"]
    at_127 = np.abs(series.command) >= 127.0
    assert at_127.sum() > 10, "the scenario must drive x into the clamp"
    np.testing.assert_array_equal(series.saturated, at_127)
    assert not fast_line.commands["y"].saturated.any()


def test_a_recorded_bag_keeps_the_flags(fast_line: RunRecord, tmp_path: Path) -> None:
    bag = read_bag(write_record_bag(fast_line, tmp_path / "fast_line"))
    for axis, series in fast_line.commands.items():
        np.testing.assert_array_equal(bag.commands[axis].saturated, series.saturated)
    assert bag.commands["x"].saturated.sum() == fast_line.commands["x"].saturated.sum() > 10
