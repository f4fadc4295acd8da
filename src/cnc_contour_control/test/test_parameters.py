"""Tier 2: config classes as declared ROS parameters and back, with real rclpy nodes (no fakes)."""
from __future__ import annotations

import math
import os
from collections.abc import Iterator
from typing import Any

import pytest
import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.context import Context
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import ParamSpec, config_values, flat_specs
from cnc_contour_control.graph.stage_params import InterpolatorRunParams, ServoRunParams
from cnc_contour_control.laws.fuzzy import FuzzyConfig
from cnc_contour_control.nodes.parameters import (
    ConfigParameters,
    Section,
    command_line_words,
    declare_config,
    given_value,
    ros_type,
    ros_value,
)
from cnc_contour_control.testing import sibling_module
from cnc_plant_sim.models.plant import MODEL_SECTIONS, PLANTS, PlantConfig

_cases = sibling_module(__file__, "test_params")  # the same config classes and bounds as the ROS-free test
CONFIGS, _outside, _with = _cases.CONFIGS, _cases._outside, _cases._with

pytestmark = pytest.mark.nodes


@pytest.fixture(scope="module")
def context() -> Iterator[Context]:
    """A context in a domain of this process's own (the root conftest's second claim), so the hundreds of nodes
    made and destroyed here meet no other participant: Fast DDS 2.14 deadlocked once in ``destroy_node`` while a
    removed writer's discovery announcement was delivered inside the process to another participant."""
    ctx = Context()
    quiet = os.environ.get("CNC_QUIET_DOMAIN_ID")
    rclpy.init(context=ctx, domain_id=int(quiet) if quiet else None)
    assert not quiet or ctx.get_domain_id() == int(quiet) != int(os.environ["ROS_DOMAIN_ID"])
    yield ctx
    rclpy.shutdown(context=ctx)


_count = iter(range(10**6))


def make_node(context: Context, overrides: dict[str, Any] | None = None) -> Node:
    """A plain node (nothing declared) with ``overrides`` as the values given for its parameters.

    Without parameter services and rosout (the tests declare, get and set parameters in process): 3 DDS endpoints
    a node, not 16. The bounds test makes two nodes a case, hundreds in all, and under load destroying their
    endpoints deadlocked in Fast DDS 2.14 (``destroy_node`` waiting in ``ResourceEvent::unregister_timer``
    while removing a writer delivered to a discovery reader in the same process): see :func:`context`.
    """
    given = [Parameter(name, value=value) for name, value in (overrides or {}).items()]
    return Node(f"params_{next(_count)}", context=context, parameter_overrides=given, start_parameter_services=False,
                enable_rosout=False)


def _by_hand(spec: Any) -> bool:
    """A free mapping or a list of pairs: no ROS parameter type holds it (a node declares such a section itself)."""
    pairs = spec.kind is list and any(isinstance(item, (list, tuple)) for item in spec.default or ())
    return (spec.kind is dict and spec.nested is None) or pairs


def _free(cls: type, base: dict[str, Any]) -> tuple[str, ...]:
    """Top-level fields holding a field no parameter can (a node fills them itself, not as parameters), and a
    plant's other models' sections (the plant node declares its model's own only)."""
    free = [s.name.split(".")[0] for s in flat_specs(cls) if _by_hand(s)]
    if cls is PlantConfig:
        own = PLANTS[base.get("model", PlantConfig.model)].section
        free += [name for name in MODEL_SECTIONS if name != own]
    return tuple(dict.fromkeys(free))


def declare(node: Node, cls: type, base: dict[str, Any]) -> Any:
    """Declare ``cls`` on ``node`` starting from ``base`` (free mappings passed by hand) and build it."""
    skip = _free(cls, base)
    kept = {k: v for k, v in base.items() if k not in skip}
    params: ConfigParameters[Any] = ConfigParameters(node, lambda m: build_config(
        cls, {**{k: v for k, v in base.items() if k in skip}, **m}))
    params.add(Section(cls, defaults=kept, skip=skip))
    return params.declare()


def _flat(mapping: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in mapping.items():
        if isinstance(value, dict):
            out.update(_flat(value, f"{prefix}{key}."))
        elif value is not None:
            out[f"{prefix}{key}"] = value
    return out


@pytest.mark.parametrize("cls", list(CONFIGS), ids=lambda c: c.__name__)
def test_a_config_class_becomes_parameters_with_its_descriptors_and_builds_again(context: Context, cls: type) -> None:
    node = make_node(context)
    try:
        config = declare(node, cls, CONFIGS[cls])
        assert config == build_config(cls, CONFIGS[cls])
        values = _flat(config_values(config))
        for spec in flat_specs(cls):
            if spec.name.split(".")[0] in _free(cls, CONFIGS[cls]):
                assert not node.has_parameter(spec.name)
                continue
            _check_descriptor(node.describe_parameter(spec.name), spec)
            kind, value = ros_type(spec, values.get(spec.name)), values.get(spec.name)
            if spec.kind is str and not isinstance(value, str):  # a name the config resolved (fuzzy rule_base)
                value = spec.default
            if isinstance(value, (list, tuple)) and not value:  # an empty array: declared typed, unset
                assert node.describe_parameter(spec.name).type == kind.value, spec.name
            elif value is not None:
                assert _plain(node.get_parameter(spec.name).value) == ros_value(kind, value), spec.name
    finally:
        node.destroy_node()


def _plain(value: Any) -> Any:
    return value if isinstance(value, (str, bool, int, float)) else list(value)


def _check_descriptor(desc: ParameterDescriptor, spec: ParamSpec) -> None:
    assert desc.description == spec.description and (not spec.info.unit or f"[{spec.info.unit}]" in desc.description)
    assert desc.read_only == spec.info.read_only
    low, high = spec.info.low, spec.info.high
    ranges = list(desc.floating_point_range) + list(desc.integer_range)
    if low is None and high is None or spec.kind not in (float, int):
        assert ranges == []
        return
    assert len(ranges) == 1
    assert ranges[0].from_value == (low if low is not None else (-math.inf if spec.kind is float else -(2**63)))
    assert ranges[0].to_value == (high if high is not None else (math.inf if spec.kind is float else 2**63 - 1))


def _declared_bounds() -> list[Any]:
    """The bounds test's cases whose field is a parameter here (sections a node declares by hand are not)."""
    return [case for case in _cases._bounds()
            if case.values[2].name.split(".")[0] not in _free(case.values[0], case.values[1])]


@pytest.mark.parametrize(("cls", "base", "spec", "bound", "direction"), _declared_bounds())
def test_a_node_takes_a_bound_and_refuses_the_next_value_with_the_configs_error(
        context: Context, cls: type, base: dict[str, Any], spec: ParamSpec, bound: float, direction: float) -> None:
    at = int(bound) if spec.kind is int else float(bound)
    beyond = _outside(spec, bound, direction)
    expected_error = ""
    try:
        build_config(cls, _with(base, spec.name, beyond))
    except ConfigError as err:
        expected_error = str(err)
    for value, accepted in ((at, True), (beyond, False)):
        node = make_node(context, {spec.name: value})
        try:
            if accepted:
                declare(node, cls, base)
                assert node.get_parameter(spec.name).value == value
            else:
                with pytest.raises(ConfigError) as err:
                    declare(node, cls, base)
                assert str(err.value) == expected_error != ""
        finally:
            node.destroy_node()


def test_an_axis_name_rcl_read_as_a_boolean_is_the_letter_and_other_strings_are_refused(context: Context) -> None:
    node = make_node(context, {"axis": True, "input_timeout_s": 2})  # -p axis:=y, -p input_timeout_s:=2
    try:
        run = declare_config(node, ServoRunParams)
        assert run.axis == "y" and node.get_parameter("axis").value == "y"
        assert run.input_timeout_s == 2.0 and node.get_parameter("input_timeout_s").type_ == Parameter.Type.DOUBLE
    finally:
        node.destroy_node()
    node = make_node(context, {"axes": [False, True]})  # -p "axes:=[n, y]"
    try:
        assert declare_config(node, InterpolatorRunParams).axes == ("n", "y")
    finally:
        node.destroy_node()
    node = make_node(context, {"frame_id": False})  # -p frame_id:=off
    try:
        with pytest.raises(ConfigError, match=r"frame_id must be a string, got the boolean false.*quote it"):
            declare_config(node, InterpolatorRunParams)
    finally:
        node.destroy_node()


def test_a_string_rcl_read_as_a_boolean_is_the_word_written_on_the_command_line() -> None:
    argv = ["servo", "-p", "x:=1", "--ros-args", "-p", "axis:=on", "--param", "servo_x:frame_id:=Off",
            "-p", "plant:frame_id:=no", "-r", "__ns:=/a", "--", "-p", "gains.kp:=3"]
    words = command_line_words(argv, "servo_x")
    assert words == {"axis": "on", "frame_id": "Off"}, "only ROS arguments, and node-scoped ones for this node"
    assert given_value("axis", Parameter.Type.STRING, True, words["axis"]) == "on"
    assert given_value("frame_id", Parameter.Type.STRING, False, words["frame_id"]) == "Off"
    assert given_value("axis", Parameter.Type.STRING, True) == "y", "a parameters file has no word: the letter"
    with pytest.raises(ConfigError, match="frame_id must be a string, got the boolean true"):
        given_value("frame_id", Parameter.Type.STRING, True, "Off")  # a word that is not this boolean


def test_a_change_is_validated_by_the_config_on_set_and_applied_after_it(context: Context) -> None:
    node = make_node(context)
    applied: list[FuzzyConfig] = []
    try:
        params: ConfigParameters[FuzzyConfig] = ConfigParameters(
            node, lambda m: build_config(FuzzyConfig, m.get("gains", {}), context="fuzzy"))
        params.add(Section(FuzzyConfig, "gains"))
        first = params.declare()
        params.watch(applied.append)
        result = node.set_parameters([Parameter("gains.e_centres", value=[-21.0, -14.0, -7.0, 0.0, 7.0, 7.0, 21.0])])[0]
        assert not result.successful and "e_centres" in result.reason and "increasing" in result.reason
        assert applied == [] and params.config == first
        result = node.set_parameters([Parameter("gains.ki", value=-1.0)])[0]
        assert not result.successful and "gains.ki" in result.reason  # the descriptor's range: the config's own
        assert node.set_parameters([Parameter("gains.ki", value=20)])[0].successful  # an integer for a double
        assert node.set_parameters([Parameter("gains.rule_base", value="paper000")])[0].successful
        assert [c.ki for c in applied] == [20.0, 20.0] and params.config is applied[-1]
        assert node.get_parameter("gains.ki").value == 20.0
    finally:
        node.destroy_node()


def test_the_plants_per_axis_overrides_are_nested_parameters_and_reach_the_plant() -> None:
    from cnc_contour_control.testing import InProcessNode
    from cnc_plant_sim.nodes.plant_node import PlantNode

    given = {"axes": ["x", "y"], "axis_overrides.y.time_constant_s": 0.06, "axis_overrides.y.friction": "table",
             "axis_overrides.y.friction_params.velocity_mm_s": [-10.0, 0.0, 10.0],
             "axis_overrides.y.friction_params.force_dac": [-12, 0, 12],  # integers for doubles, as rcl reads 12
             "axis_overrides.x.friction_params.scale": 2.0, "variation.gain_pct": 0.0}
    with InProcessNode(PlantNode, given) as plant:
        axes = plant.node.plant.describe()["axes"]
        described = plant.node.describe_parameter("axis_overrides.y.time_constant_s")
        assert described.read_only and "[s]" in described.description
        with pytest.raises(ParameterUninitializedException):  # an override not given stays unset
            plant.node.get_parameter("axis_overrides.x.time_constant_s")
    assert axes["y"]["nominal_time_constant_s"] == 0.06 and axes["y"]["friction"] == "table"
    assert axes["y"]["friction_params"] == {"velocity_mm_s": [-10.0, 0.0, 10.0], "force_dac": [-12.0, 0.0, 12.0]}
    assert axes["x"]["friction"] == "paper000_x" and axes["x"]["friction_params"] == {"scale": 2.0}
    assert axes["x"]["gain_blu_s_per_dac"] == axes["x"]["nominal_gain_blu_s_per_dac"] == 28.35
