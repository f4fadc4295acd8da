"""Issue 23: a scenario's ``limits.travel_mm`` and ``homing`` sections, their refusals, and the nodes' parameters."""
from __future__ import annotations

from pathlib import Path

import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import load_scenario

SHOP = Path(__file__).resolve().parents[3] / "scenarios" / "gcode_shop.yaml"


def test_the_shop_scenario_carries_its_travel_and_the_nodes_get_it(tmp_path: Path) -> None:
    scenario = load_scenario(SHOP)
    assert scenario.travel.limit_mm("x") == (-2.0, 300.0) and scenario.travel.limit_mm("y") == (-2.0, 200.0)
    specs = {spec.name: spec.parameters for spec in graph_specs(scenario, tmp_path)}
    assert specs["interpolator"]["travel_axes"] == ["x", "y"]
    assert specs["interpolator"]["travel_min_mm"] == [-2.0, -2.0]
    assert specs["interpolator"]["travel_max_mm"] == [300.0, 200.0]
    assert specs["servo_x"]["travel_mm"] == [-2.0, 300.0]
    assert "home_position_mm" not in specs["interpolator"]  # no homing section: the nodes' defaults


@pytest.mark.parametrize("travel, words", [
    ({"x": [-2, 29]}, "scenario.limits.travel_mm: travel limit: line 8 takes axis x to 30.000000 mm, 1.000000 mm "
                      "beyond its travel_max_mm 29"),  # N60's long arc, centre X20 Y5 + G55's 5: x 30
    ({"x": [0.5, 300]}, "line 4 takes axis x to 0.000000 mm, 0.500000 mm beyond its travel_min_mm 0.5"),  # N20's G0
    # from machine zero: the first segment in program order that leaves the box is named
    ({"z": [0, 1]}, "scenario.limits.travel_axes names 'z'"),
    ({"x": [3, 1]}, "scenario.limits.travel_min_mm must be < travel_max_mm for axis x"),
    ({"x": 5}, "travel_mm.x must be [min_mm, max_mm], got 5"),
])
def test_a_travel_the_planned_path_leaves_or_a_bad_one_is_refused_naming_it(travel: dict, words: str) -> None:
    with pytest.raises(ConfigError) as refused:
        load_scenario(SHOP, {"limits": {"travel_mm": travel}})
    assert words in str(refused.value)


def test_a_homing_section_becomes_the_interpolators_parameters(tmp_path: Path) -> None:
    scenario = load_scenario(SHOP, {"homing": {"position_mm": {"x": 1.5}, "feed_mm_min": {"x": 600, "y": 300}}})
    assert scenario.homing.home_position_mm == (1.5, 0.0) and scenario.homing.homing_feed_mm_min == (600.0, 300.0)
    interpolator = next(s.parameters for s in graph_specs(scenario, tmp_path) if s.name == "interpolator")
    assert interpolator["home_position_mm"] == [1.5, 0.0] and interpolator["homing_feed_mm_min"] == [600.0, 300.0]
    assert interpolator["require_homing"] is False


@pytest.mark.parametrize("homing, words", [
    ({"position_mm": {"x": 400}}, "scenario.homing.home_position_mm of axis x must be within its travel [-2, 300] mm, "
                                  "got 400"),
    ({"position_mm": {"q": 1}}, "scenario.homing.position_mm.q: unknown key"),
    ({"feed_mm_min": {"x": 600}}, "scenario.homing.feed_mm_min needs every axis"),
    ({"feed_mm_min": 0}, "homing_feed_mm_min must be > 0"),
    ({"require_homing": True}, "scenario.homing.require_homing needs the interpolator's action mode"),
    ({"speed": 1}, "scenario.homing.speed: unknown key"),
])
def test_a_bad_homing_section_is_refused_naming_the_key(homing: dict, words: str) -> None:
    with pytest.raises(ConfigError) as refused:
        load_scenario(SHOP, {"homing": homing})
    assert words in str(refused.value)
