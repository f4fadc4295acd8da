"""What a user's file may give as a number: YAML 1.2 floats are numbers, a boolean never is (issue 22)."""
from __future__ import annotations

import datetime
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cnc_contour_control.core.config import load_yaml, read_yaml_mapping, require_finite, require_positive
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param


@pytest.mark.parametrize(("text", "number"), [
    ("1e-3", 1e-3), ("24e-1", 2.4), ("+1.5E+2", 150.0), ("1.0e6", 1e6), ("-8e-4", -8e-4), ("1E3", 1000.0),
    ("2.5", 2.5), (".5", 0.5), ("1.", 1.0), ("1.0e-6", 1e-6),
])
def test_yaml_1_2_floats_are_numbers(text: str, number: float) -> None:
    value = load_yaml(text)
    assert isinstance(value, float) and value == number, f"{text!r} read as {value!r}"


@pytest.mark.parametrize(("text", "value"), [
    ("10", 10), ("0x1f", 31), ("-3", -3), ("1e", "1e"), ("e3", "e3"), ("3e+", "3e+"), ("1.2.3", "1.2.3"),
    ("yes", True), ("x", "x"), ("2001-12-14", datetime.date(2001, 12, 14)), ("'1e-3'", "1e-3"),
])
def test_everything_else_reads_as_before(text: str, value: Any) -> None:
    read = load_yaml(text)
    assert read == value and type(read) is type(value), f"{text!r} read as {read!r}"


def test_inf_and_nan_stay_floats() -> None:
    assert load_yaml(".inf") == math.inf and math.isnan(load_yaml(".nan"))


def test_a_scenario_style_file_reads_its_exponent_floats_as_numbers(tmp_path: Path) -> None:
    path = tmp_path / "scenario.yaml"
    path.write_text("servo:\n  law_params:\n    kp: 24e-1\n  min_ferror_m: 8e-4\n")
    assert read_yaml_mapping(path, "scenario file") == {"servo": {"law_params": {"kp": 2.4}, "min_ferror_m": 8e-4}}


@pytest.mark.parametrize("value", [True, False, np.True_, np.bool_(False)])
def test_a_boolean_is_no_number(value: Any) -> None:
    with pytest.raises(ConfigError, match=rf"^program.radius_mm must be a number, got {value!r}$"):
        require_finite("radius_mm", value, "program")
    with pytest.raises(ConfigError, match="radius_mm must be a number"):
        require_positive("radius_mm", value)


@dataclass(frozen=True)
class _Gains:
    kp: float = param(1.0, unit="dac/count", low=0.0, high=10.0)
    offset: float = param(0.0, unit="dac")  # no range: a boolean was let through
    steps: int = param(3)

    def __post_init__(self) -> None:
        check_ranges(self, "gains")


@pytest.mark.parametrize(("field", "value"), [("kp", True), ("offset", True), ("offset", False), ("steps", True)])
def test_a_declared_number_refuses_a_boolean_with_or_without_a_range(field: str, value: bool) -> None:
    with pytest.raises(ConfigError, match=rf"^gains.{field} must be a number, got {value}$"):
        _Gains(**{field: value})


def test_declared_numbers_still_take_numbers() -> None:
    assert _Gains(kp=2, offset=-1.5, steps=4) == _Gains(kp=2.0, offset=-1.5, steps=4)
