"""The launch file starts the runner's nodes with the runner's parameter files, and the nodes read them as written.

``launch`` and ``launch_ros`` are not available as wheels here, so the test
loads the launch file itself (it imports ``launch`` only inside
``generate_launch_description``), takes the nodes it would start from its own
``graph_nodes``, checks with ``ast`` that each becomes a ``launch_ros`` Node
with exactly that package, executable, name, namespace and parameters file,
and resolves every file twice as launch would have it resolved: by rclpy's
``parameter_dict_from_yaml_file`` and by rcl itself, starting the node class
with ``--ros-args --params-file`` (what ``launch_ros`` passes to the process).
"""
from __future__ import annotations

import ast
import importlib.util
from pathlib import Path
from typing import Any

import pytest
import rclpy
from rclpy.context import Context
from rclpy.parameter import parameter_dict_from_yaml_file, parameter_value_to_python

from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_plant_sim.nodes.plant_node import PlantNode
from cnc_tools.cli.common import parse_overrides
from cnc_tools.cli.main import main
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import load_scenario

pytestmark = pytest.mark.nodes
LAUNCH_FILE = Path(__file__).resolve().parents[1] / "launch" / "contour_graph.launch.py"
SCENARIO = Path(__file__).resolve().parents[3] / "scenarios" / "helix_3axis.yaml"
#: Axis y gets a table friction and a time constant, as nested parameters of the plant.
SETS = ["plant.axis_overrides.y.time_constant_s=0.06", "plant.axis_overrides.y.friction=table",
        "plant.axis_overrides.y.friction_params.velocity_mm_s=[-10.0, 0.0, 10.0]",
        "plant.axis_overrides.y.friction_params.force_dac=[-12.0, 0.0, 12.0]"]
NODE_CLASSES = {"plant": PlantNode, "interpolator": InterpolatorNode, "servo": ServoNode}


def load_launch_file() -> Any:
    spec = importlib.util.spec_from_file_location("contour_graph_launch", LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def flat(mapping: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in mapping.items():
        if isinstance(value, dict):
            out.update(flat(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def as_declared(value: Any) -> Any:
    return value if isinstance(value, (str, bool, int, float)) else list(value)


def test_the_launch_file_starts_the_runners_nodes_with_the_runners_parameters(tmp_path: Path) -> None:
    folder = tmp_path / "graph"
    assert main(["params", str(SCENARIO), "--out", str(folder), *[a for s in SETS for a in ("--set", s)]]) == 0
    scenario = load_scenario(SCENARIO, parse_overrides(SETS))
    runner = {spec.name: spec for spec in graph_specs(scenario, folder)}  # what `cnc-contour run` starts
    nodes = load_launch_file().graph_nodes(str(folder))
    assert [(n.package, n.executable, n.name) for n in nodes] == [
        (s.package, s.executable, s.name) for s in runner.values()]
    assert {n.name for n in nodes} == {"plant", "interpolator", "servo_x", "servo_y", "servo_z"}
    for node in nodes:
        written = flat(runner[node.name].parameters)
        resolved = parameter_dict_from_yaml_file(str(node.parameters_file), target_nodes=[node.full_name])
        assert {k: parameter_value_to_python(v.value) for k, v in resolved.items()} == written, node.name
        declared = started_with_params_file(node)
        assert {name: declared[name] for name in written} == {k: as_declared(v) for k, v in written.items()}, \
            f"{node.name} reads every parameter the runner writes, with the same value"
    assert runner["servo_y"].parameters["axis"] == "y"
    assert written_y_override(runner["plant"].parameters) == {"time_constant_s": 0.06, "friction": "table"}


def written_y_override(plant: Any) -> dict[str, Any]:
    override = dict(plant["axis_overrides"]["y"])
    override.pop("friction_params")
    return override


def started_with_params_file(node: Any) -> dict[str, Any]:
    """The node class started as launch_ros starts the process: ``--ros-args -r __ns -r __node --params-file``."""
    context = Context()
    rclpy.init(context=context, args=["--ros-args", "-r", f"__ns:={node.namespace}", "-r", f"__node:={node.name}",
                                      "--params-file", str(node.parameters_file)])
    try:
        instance = NODE_CLASSES[node.executable](context=context)
        try:
            parameters = instance.get_parameters_by_prefix("")
            return {name: as_declared(p.value) for name, p in parameters.items() if p.value is not None}
        finally:
            instance.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_each_node_of_the_folder_becomes_a_launch_ros_node_with_its_parameters_file() -> None:
    tree = ast.parse(LAUNCH_FILE.read_text())
    functions = {f.name: f for f in tree.body if isinstance(f, ast.FunctionDef)}
    launch = functions["generate_launch_description"]
    assert any(isinstance(k.value, ast.Name) and k.value.id == "node_actions"
               for call in ast.walk(launch) if isinstance(call, ast.Call)
               and getattr(call.func, "id", "") == "OpaqueFunction" for k in call.keywords)
    comprehension = next(c for c in ast.walk(functions["node_actions"]) if isinstance(c, ast.ListComp))
    source = comprehension.generators[0].iter
    assert isinstance(source, ast.Call) and getattr(source.func, "id", "") == "graph_nodes"
    target = comprehension.generators[0].target.id  # type: ignore[attr-defined]
    call = comprehension.elt
    assert isinstance(call, ast.Call) and getattr(call.func, "id", "") == "Node"
    keywords = {k.arg: k.value for k in call.keywords}
    for name in ("package", "executable", "name", "namespace"):
        assert ast.unparse(keywords[name]) == f"{target}.{name}"
    assert ast.unparse(keywords["parameters"]) == f"[str({target}.parameters_file)]"
