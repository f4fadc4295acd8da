"""Scenarios: the shipped ones load; bad ones are refused naming the key, the bound and the value."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from cnc_contour_control.core.errors import ConfigError, ProgramError
from cnc_plant_sim.models.plant import MODEL_SECTIONS, PLANTS
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SHIPPED = sorted((ROOT / "scenarios").glob("*.yaml"))


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_scenarios_load(path: Path) -> None:
    scenario = load_scenario(path)
    assert scenario.axes == tuple(scenario.program.axis_names) and len(scenario.servos) == len(scenario.axes)
    if scenario.force_regulator is None:  # a regulated cut sets its own pace: its run is bounded by the process's time
        assert scenario.duration_s > scenario.make_interpolator().duration_s
    else:
        assert scenario.duration_s == pytest.approx(12.0)  # paper 004's scenario: 12 s of cutting


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_the_plant_node_of_a_shipped_scenario_gets_its_models_section_only(path: Path, tmp_path: Path) -> None:
    scenario = load_scenario(path)
    plant = next(spec.parameters for spec in graph_specs(scenario, tmp_path) if spec.name == "plant")
    assert set(plant) & set(MODEL_SECTIONS) == {PLANTS[scenario.plant.model].section}
    assert ("periodic_load" in plant) == scenario.plant.periodic_load.active


def test_paper000_six_table5_scenarios_are_shipped() -> None:
    names = {p.stem for p in SHIPPED}
    assert {f"paper000_{c}_{f}" for c in ("line", "circle", "corner") for f in ("low", "high")} <= names


def _write(tmp_path: Path, overrides: dict) -> Path:
    base = yaml.safe_load((ROOT / "scenarios" / "paper000_circle_high.yaml").read_text())
    for key, value in overrides.items():
        node = base
        *parents, leaf = key.split(".")
        for part in parents:
            node = node[part]
        if value is _DELETE:
            del node[leaf]
        else:
            node[leaf] = value
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(base))
    return path


_DELETE = object()
ARC_OFF_CIRCLE = {"axes": ["x", "y"], "start_mm": [0, 0], "feed_mm_min": 400,
                  "segments": [{"arc": {"to_mm": [20, 21], "center_mm": [0, 20], "direction": "ccw"}}]}


@pytest.mark.parametrize(
    ("overrides", "error", "words"),
    [
        ({"colour": "red"}, ConfigError, ["colour", "unknown key"]),
        ({"servo.gain": 3}, ConfigError, ["gain", "unknown key"]),
        ({"program.radius_mm": -3}, ConfigError, ["radius_mm", "> 0", "-3"]),
        ({"program.feed_mm_min": 0}, ConfigError, ["feed_mm_min", "> 0", "0"]),
        ({"program": ARC_OFF_CIRCLE}, ProgramError, ["segment 0", "radius"]),
        ({"limits.max_velocity_mm_min": 1000}, ProgramError, ["feed_mm_min", "1300", "1000"]),
        ({"limits.max_acceleration_mm_s2": -5}, ConfigError, ["max_acceleration_mm_s2", "> 0", "-5"]),
        ({"sample_time_s": 0}, ConfigError, ["sample_time_s", "> 0"]),
        ({"mode": "fast"}, ConfigError, ["mode", "lockstep", "fast"]),
        ({"servo.law": "magic"}, ConfigError, ["magic", "pid"]),
        ({"plant.model": "lathe"}, ConfigError, ["lathe", "paper000"]),
        ({"plant.velocity_loop": {"spindle_rpm": 0}}, ConfigError,
         ["scenario.plant.velocity_loop", "a section of plant model(s) ['paper002', 'paper003']", "'paper000'"]),
        ({"plant.variation.noise_pct": 1}, ConfigError, ["variation.noise_pct", "unknown key", "'paper000'"]),
        ({"plant.spindle_rpm": 1}, ConfigError,
         ["scenario.plant.spindle_rpm", "unknown key of plant model 'paper000'"]),
        ({"servo.follow_spindle": True}, ConfigError, ["follow_spindle", "velocity_loop", "'paper000'"]),
    ],
)
def test_bad_scenarios_are_refused_naming_the_problem(tmp_path: Path, overrides: dict, error: type,
                                                      words: list[str]) -> None:
    with pytest.raises(error) as caught:
        load_scenario(_write(tmp_path, overrides))
    for word in words:
        assert word in str(caught.value), (word, str(caught.value))


def test_missing_scenario_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="nowhere.yaml"):
        load_scenario(tmp_path / "nowhere.yaml")
