"""``kp: 24e-1`` in a scenario and ``--set servo.min_ferror_m=8e-4`` are numbers, as YAML 1.2 reads them (issue 22).

PyYAML's YAML 1.1 resolver read a float without a dot as a string, and the
scenario then refused it as "not a number".
"""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from cnc_contour_control.core.errors import CncError
from cnc_tools.cli.common import parse_overrides
from cnc_tools.cli.main import main
from cnc_tools.runs.scenario import load_scenario

CIRCLE = Path(__file__).resolve().parents[3] / "scenarios" / "paper000_circle_high.yaml"


def _with_exponent_kp(tmp_path: Path) -> Path:
    text = CIRCLE.read_text()
    assert "    kp: 2.4 " in text
    path = tmp_path / "scenario.yaml"
    path.write_text(text.replace("    kp: 2.4 ", "    kp: 24e-1 "))
    return path


def test_set_values_read_yaml_1_2_floats() -> None:
    assert parse_overrides(["servo.min_ferror_m=8e-4", "sample_time_s=+1E-3", "seed=3", "servo.law=pid"]) == {
        "servo": {"min_ferror_m": 8e-4, "law": "pid"}, "sample_time_s": 1e-3, "seed": 3}


def test_a_set_value_that_is_not_yaml_names_the_key() -> None:
    with pytest.raises(CncError, match=r"^--set servo.law: '\[pid' is not a YAML value"):
        parse_overrides(["servo.law=[pid"])


def test_a_scenario_file_and_a_set_value_with_exponent_floats_load(tmp_path: Path) -> None:
    scenario = load_scenario(_with_exponent_kp(tmp_path), parse_overrides(["servo.min_ferror_m=8e-4"]))
    assert [s.law_params["kp"] for s in scenario.servos] == [2.4, 2.4]
    assert [s.min_ferror_m for s in scenario.servos] == [8e-4, 8e-4]


def test_the_params_command_writes_them_as_numbers(tmp_path: Path) -> None:
    out = tmp_path / "params"
    assert main(["params", str(_with_exponent_kp(tmp_path)), "--out", str(out),
                 "--set", "servo.min_ferror_m=8e-4"]) == 0
    servo = yaml.safe_load((out / "servo_x.params.yaml").read_text())["/cnc/servo_x"]["ros__parameters"]
    assert (servo["gains"]["kp"], servo["min_ferror_m"]) == (2.4, 8e-4)
