"""A graph in one parameters file: shared values under ``/**``, sections as the nodes to start."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.graph.graph_params import (
    SHARED_SECTION,
    flatten,
    graph_params_yaml,
    nest,
    read_graph_params,
    shared_parameters,
    stage_of,
)

SERVO = {"sample_time_s": 0.01, "law": "pid", "gains": {"kp": 2.4, "ki": 10.0}}
NODES: list[tuple[str, dict[str, Any]]] = [
    ("plant", {"sample_time_s": 0.01, "axes": ["x", "y"], "required_readers": ["servo_x", "servo_y"]}),
    ("interpolator", {"axes": ["x", "y"], "min_subscribers": 2, "program_file": "p.yaml"}),
    ("servo_x", {**SERVO, "axis": "x", "min_subscribers": 1}),
    ("servo_y", {**SERVO, "axis": "y", "min_subscribers": 1}),
]


def resolved(document: dict[str, Any], full_name: str) -> dict[str, Any]:
    """What rcl gives ``full_name`` from the document: ``/**`` then its own section (flat)."""
    shared = flatten(document.get(SHARED_SECTION, {}).get("ros__parameters", {}))
    return {**shared, **flatten(document[full_name]["ros__parameters"])}


def test_flatten_and_nest_are_inverse() -> None:
    nested = {"a": 1, "gains": {"kp": 2.0, "inner": {"x": [1, 2]}}, "b": "y"}
    assert flatten(nested) == {"a": 1, "gains.kp": 2.0, "gains.inner.x": [1, 2], "b": "y"}
    assert nest(flatten(nested)) == nested


def test_every_node_resolves_to_its_own_parameters_and_shared_values_are_written_once() -> None:
    document = yaml.safe_load(graph_params_yaml("/cnc", NODES))
    assert list(document) == [SHARED_SECTION, "/cnc/plant", "/cnc/interpolator", "/cnc/servo_x", "/cnc/servo_y"]
    for name, parameters in NODES:  # (a node ignores the shared values it does not declare: test_installed_params)
        given = resolved(document, f"/cnc/{name}")
        assert {k: v for k, v in given.items() if k in flatten(parameters)} == flatten(parameters), name
    assert flatten(document[SHARED_SECTION]["ros__parameters"]) == {
        "sample_time_s": 0.01, "axes": ["x", "y"], "law": "pid", "gains.kp": 2.4, "gains.ki": 10.0}
    assert "min_subscribers" in document["/cnc/servo_x"]["ros__parameters"], "1 and 2 differ: not shared"


@pytest.mark.parametrize("values", [[1, 1.0], [True, 1], [0.01, 0.02], ["x", "y"]])
def test_values_that_differ_in_value_or_type_are_not_shared(values: list[Any]) -> None:
    assert shared_parameters([{"p": v} for v in values]) == {}
    assert shared_parameters([{"p": values[0]}, {"p": values[0]}]) == {"p": values[0]}
    assert shared_parameters([{"p": values[0]}]) == {}, "one node: nothing to share"


def test_strings_are_quoted_so_rcl_reads_axis_y_as_a_string() -> None:
    text = graph_params_yaml("/cnc", [("servo_y", {"axis": "y"})])
    assert '"axis": "y"' in text


@pytest.mark.parametrize(("node", "stage", "package", "executable"), [
    ("plant", "plant", "cnc_plant_sim", "plant"),
    ("interpolator", "interpolator", "cnc_contour_control", "interpolator"),
    ("servo_x", "servo", "cnc_contour_control", "servo"),
    ("servo_spindle", "servo", "cnc_contour_control", "servo"),
    ("compensator", "compensator", "cnc_contour_control", "compensator"),
])
def test_a_node_name_names_its_stage(node: str, stage: str, package: str, executable: str) -> None:
    found = stage_of(node)
    assert (found.name, found.package, found.executable) == (stage, package, executable)


@pytest.mark.parametrize("node", ["servo", "servo_", "plantx", "recorder_x"])
def test_a_name_that_is_no_stages_node_is_refused_listing_the_names(node: str) -> None:
    with pytest.raises(ConfigError, match=rf"node '{node}' is no stage's node; node names: .*'servo_<axis>'"):
        stage_of(node)


def test_the_file_lists_its_nodes_with_package_executable_namespace_and_itself(tmp_path: Path) -> None:
    path = tmp_path / "graph.params.yaml"
    path.write_text(graph_params_yaml("/cnc/bench", NODES))
    nodes = read_graph_params(path)
    assert [(n.name, n.package, n.executable, n.namespace) for n in nodes] == [
        ("plant", "cnc_plant_sim", "plant", "/cnc/bench"),
        ("interpolator", "cnc_contour_control", "interpolator", "/cnc/bench"),
        ("servo_x", "cnc_contour_control", "servo", "/cnc/bench"),
        ("servo_y", "cnc_contour_control", "servo", "/cnc/bench")]
    assert {n.parameters_file for n in nodes} == {path.resolve()}
    assert nodes[2].full_name == "/cnc/bench/servo_x"


@pytest.mark.parametrize(("content", "message"), [
    ({"/**": {"ros__parameters": {"a": 1}}}, "names no node"),
    ({"plant": {"ros__parameters": {"a": 1}}}, "section 'plant' must be a fully qualified node name"),
    ({"/cnc/plant": {"a": 1}}, "section '/cnc/plant' must be .* holding ros__parameters"),
    ({"/cnc/bag": {"ros__parameters": {"a": 1}}}, "node 'bag' is no stage's node; node names: .*'recorder'"),
])
def test_a_file_that_is_no_graph_is_refused_naming_what_is_wrong(tmp_path: Path, content: Any, message: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(content))
    with pytest.raises(ConfigError, match=message):
        read_graph_params(path)


def test_the_recorder_is_a_node_of_a_graph(tmp_path: Path) -> None:
    path = tmp_path / "recorded.params.yaml"
    path.write_text(graph_params_yaml("/cnc", [("recorder", {"latched_first": True}), *NODES]))
    assert [(n.name, n.package, n.executable) for n in read_graph_params(path)][:2] == [
        ("recorder", "cnc_tools", "recorder"), ("plant", "cnc_plant_sim", "plant")]


def test_no_nodes_is_refused() -> None:
    with pytest.raises(ConfigError, match="at least one node, got none"):
        graph_params_yaml("/cnc", [])
