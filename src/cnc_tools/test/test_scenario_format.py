"""Tier 1: the scenario format's version, and gains written per sample before format 2 refused with the conversion."""
from __future__ import annotations

import pickle
from pathlib import Path

import pytest
import yaml

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.verdict import judge
from cnc_tools.runs.engine import EngineFault, run_engine
from cnc_tools.runs.scenario import load_scenario
from cnc_tools.runs.scenario_format import FORMAT_VERSION

ROOT = Path(__file__).resolve().parents[3]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
#: Paper 000's Table 4 as printed, per sample at T = 10 ms.
PER_SAMPLE = {"servo": {"law_params": {"kp": 2.4, "ki": 0.1, "kd": 6.7}}}


def _without_version(tmp_path: Path) -> Path:
    raw = yaml.safe_load(CIRCLE.read_text())
    raw.pop("format_version")
    path = tmp_path / "old.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


@pytest.mark.parametrize("path", sorted((ROOT / "scenarios").rglob("*.yaml")), ids=lambda p: p.stem)
def test_every_shipped_scenario_states_the_format(path: Path) -> None:
    assert yaml.safe_load(path.read_text())["format_version"] == FORMAT_VERSION


def test_a_file_without_a_version_and_per_sample_gains_is_refused_with_the_conversion(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as err:
        load_scenario(_without_version(tmp_path), PER_SAMPLE)
    text = str(err.value)
    assert "no format_version" in text and "kd = 6.7" in text
    assert "ki = 0.1 / 0.01 = 10" in text and "kd = 6.7 * 0.01 = 0.067" in text, text
    assert "format_version: 2" in text


def test_a_file_without_a_version_and_gains_in_time_units_loads(tmp_path: Path) -> None:
    scenario = load_scenario(_without_version(tmp_path))
    assert scenario.servos[0].law_params["kd"] == pytest.approx(0.067)


@pytest.mark.parametrize("version", [1, 3, "2", True])
def test_another_version_is_refused_naming_the_one_read(version: object) -> None:
    with pytest.raises(ConfigError, match=r"scenario.format_version must be 2 .*got"):
        load_scenario(CIRCLE, {"format_version": version})


def test_per_sample_gains_run_as_time_units_trip_the_default_following_error_bound() -> None:
    """The old finding: per-sample gains read as time units ran unstable to 90 mm of error and ended COMPLETE.
    With the trip on by default the run faults within its first second, naming the axis."""
    with pytest.raises(EngineFault) as fault:
        run_engine(load_scenario(CIRCLE, PER_SAMPLE))
    record = fault.value.record
    verdict = judge(record)
    assert verdict.status == "faulted" and "following error" in verdict.describe(), verdict.describe()
    assert record.summary["simulated_time_s"] < 2.0, "tripped early, before the error grew to centimetres"
    back = pickle.loads(pickle.dumps(fault.value))  # as a pool's worker returns it
    assert isinstance(back, EngineFault) and str(back) == str(fault.value)
    assert back.record.summary == record.summary
