"""Tier 1: a scenario's ``realtime`` section sets the plant's real-time watchdog (no ROS)."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SCENARIO = ROOT / "scenarios" / "paper000_circle_high.yaml"


def _scenario(tmp_path: Path, realtime: object) -> Path:
    raw = yaml.safe_load(SCENARIO.read_text())
    raw["realtime"] = realtime
    path = tmp_path / "realtime.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def _plant_parameters(scenario_file: Path, tmp_path: Path) -> dict[str, object]:
    specs = graph_specs(load_scenario(scenario_file), tmp_path)
    return next(spec.parameters for spec in specs if spec.name.endswith("plant"))


def test_the_section_reaches_the_plant_and_the_rest_keep_their_defaults(tmp_path: Path) -> None:
    given = _plant_parameters(_scenario(tmp_path, {"max_period_ratio": 0.0, "max_late_share": 0.5}), tmp_path)
    plain = _plant_parameters(SCENARIO, tmp_path)
    assert (given["max_period_ratio"], given["max_late_share"]) == (0.0, 0.5)
    assert (plain["max_period_ratio"], plain["max_late_share"]) == (2.0, 0.25)
    assert given["late_window_ticks"] == plain["late_window_ticks"] == 100


@pytest.mark.parametrize(("realtime", "words"), [
    ({"max_period_ratio": -1.0}, ["scenario.realtime.max_period_ratio", "-1"]),
    ({"max_late_share": 1.5}, ["scenario.realtime.max_late_share", "1.5"]),
    ({"period_ratio": 3.0}, ["scenario.realtime.period_ratio", "unknown key", "max_period_ratio"]),
    ([1, 2], ["scenario.realtime must be a mapping"]),
])
def test_bad_realtime_options_are_refused_naming_the_option(tmp_path: Path, realtime: object,
                                                            words: list[str]) -> None:
    with pytest.raises(ConfigError) as caught:
        load_scenario(_scenario(tmp_path, realtime))
    for word in words:
        assert word in str(caught.value), (word, str(caught.value))
