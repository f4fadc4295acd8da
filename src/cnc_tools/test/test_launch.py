"""The launch file starts a whole graph from one parameters file (or a runner's folder) and ends with the plant.

``launch`` and ``launch_ros`` are not available as wheels here, so the test
loads the launch file itself (it imports ``launch`` only inside the functions
that build actions) and runs it against recording stand-ins of the launch
API: each node of the graph becomes a ``launch_ros`` Node with exactly its
package, executable, name, namespace, parameters file and folder, and the
plant's exit is registered to shut the launch down. Where ``launch_ros`` is
installed (a system Jazzy), the real API builds the same actions. The
runner's folder (``params_dir``) is resolved as launch would have it resolved:
by rclpy's ``parameter_dict_from_yaml_file`` and by rcl itself, starting the
node class with ``--ros-args --params-file`` (what ``launch_ros`` passes to
the process); the one-file form is checked so in ``test_installed_params.py``.
"""
from __future__ import annotations

import importlib.util
import sys
import types
from pathlib import Path
from typing import Any

import pytest
import rclpy
from rclpy.context import Context
from rclpy.parameter import parameter_dict_from_yaml_file, parameter_value_to_python

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.graph.graph_params import graph_params_yaml
from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_plant_sim.nodes.plant_node import PlantNode
from cnc_tools.cli.common import parse_overrides
from cnc_tools.cli.main import main
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import load_scenario

pytestmark = pytest.mark.nodes
LAUNCH_FILE = Path(__file__).resolve().parents[2] / "cnc_contour_bringup" / "launch" / "contour_graph.launch.py"
SCENARIO = Path(__file__).resolve().parents[3] / "scenarios" / "helix_3axis.yaml"
#: Axis y gets a table friction and a time constant, as nested parameters of the plant.
SETS = ["plant.axis_overrides.y.time_constant_s=0.06", "plant.axis_overrides.y.friction=table",
        "plant.axis_overrides.y.friction_params.velocity_mm_s=[-10.0, 0.0, 10.0]",
        "plant.axis_overrides.y.friction_params.force_dac=[-12.0, 0.0, 12.0]"]
NODE_CLASSES = {"plant": PlantNode, "interpolator": InterpolatorNode, "servo": ServoNode}


def load_launch_file() -> Any:
    spec = importlib.util.spec_from_file_location("contour_graph_launch", LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]  # the file exists: a spec
    spec.loader.exec_module(module)  # type: ignore[union-attr]  # a source file's spec has a loader
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


class Recorded:
    """A stand-in for a ``launch``/``launch_ros`` class: keeps its arguments."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


class LaunchConfiguration(Recorded):
    def perform(self, context: dict[str, str]) -> str:
        return context[self.args[0]] if self.args[0] in context else str(self.kwargs["default"])


def fake_launch_api(monkeypatch: pytest.MonkeyPatch) -> dict[str, type]:
    """The names the launch file imports, as recording stand-ins (``launch`` has no wheels here)."""
    kinds = {name: type(name, (Recorded,), {}) for name in (
        "LaunchDescription", "DeclareLaunchArgument", "OpaqueFunction", "RegisterEventHandler", "Shutdown",
        "OnProcessExit", "PathJoinSubstitution", "Node", "FindPackageShare")}
    kinds["LaunchConfiguration"] = LaunchConfiguration
    modules = {"launch": ["LaunchDescription"], "launch.actions": [
        "DeclareLaunchArgument", "OpaqueFunction", "RegisterEventHandler", "Shutdown"],
        "launch.event_handlers": ["OnProcessExit"], "launch.substitutions": ["LaunchConfiguration",
                                                                            "PathJoinSubstitution"],
        "launch_ros": [], "launch_ros.actions": ["Node"], "launch_ros.substitutions": ["FindPackageShare"]}
    for module_name, names in modules.items():
        module = types.ModuleType(module_name)
        for name in names:
            setattr(module, name, kinds[name])
        monkeypatch.setitem(sys.modules, module_name, module)
    return kinds


def installed_params_file() -> Path:
    config_dir = Path(__file__).resolve().parents[2] / "cnc_contour_control" / "config"
    return config_dir / load_launch_file().DEFAULT_PARAMS_FILE


def test_the_launch_file_starts_every_node_of_one_file_and_shuts_down_when_the_plant_exits(
        monkeypatch: pytest.MonkeyPatch) -> None:
    kinds = fake_launch_api(monkeypatch)
    launch = load_launch_file()
    description = launch.generate_launch_description()
    arguments = {a.args[0]: a.kwargs for a in description.args[0] if isinstance(a, kinds["DeclareLaunchArgument"])}
    assert arguments["params_dir"]["default_value"] == arguments["bag"]["default_value"] == ""
    default = arguments["params_file"]["default_value"]
    assert default.args[0][0].args == ("cnc_contour_control",) and default.args[0][1:] == [
        "config", launch.DEFAULT_PARAMS_FILE]
    opaque = next(a for a in description.args[0] if isinstance(a, kinds["OpaqueFunction"]))
    params_file = installed_params_file()
    actions = opaque.kwargs["function"]({"params_file": str(params_file), "params_dir": "", "bag": ""})
    nodes = [a for a in actions if isinstance(a, kinds["Node"])]
    expected = launch.graph_nodes(params_file)
    assert [n.name for n in expected] == ["plant", "interpolator", "servo_x", "servo_y"]
    assert [node.kwargs for node in nodes] == [
        {"package": n.package, "executable": n.executable, "name": n.name, "namespace": n.namespace,
         "parameters": [str(params_file.resolve())], "cwd": str(params_file.resolve().parent), "output": "screen"}
        for n in expected]
    handlers = [a for a in actions if isinstance(a, kinds["RegisterEventHandler"])]
    assert len(handlers) == 1 and isinstance(handlers[0].args[0], kinds["OnProcessExit"])
    on_exit = handlers[0].args[0].kwargs
    assert on_exit["target_action"] is nodes[0] and nodes[0].kwargs["name"] == "plant"
    assert [type(a) for a in on_exit["on_exit"]] == [kinds["Shutdown"]]


def test_a_recorded_graph_writes_its_bag_to_the_bag_argument_and_ends_with_the_recorder(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    kinds = fake_launch_api(monkeypatch)
    launch = load_launch_file()
    params_file = installed_params_file().with_name("paper000_circle_high.recorded.params.yaml")
    with pytest.raises(ConfigError, match="the graph records; give the bag folder: bag:=DIR"):
        launch.node_actions({"params_file": str(params_file), "params_dir": "", "bag": ""})
    actions = launch.node_actions({"params_file": str(params_file), "params_dir": "", "bag": str(tmp_path / "bag")})
    nodes = {a.kwargs["name"]: a for a in actions if isinstance(a, kinds["Node"])}
    assert list(nodes) == ["recorder", "plant", "interpolator", "servo_x", "servo_y"]
    assert nodes["recorder"].kwargs["parameters"] == [str(params_file.resolve()), {"output": str(tmp_path / "bag")}]
    assert nodes["plant"].kwargs["parameters"] == [str(params_file.resolve())]
    handlers = {h.args[0].kwargs["target_action"].kwargs["name"]: h.args[0].kwargs["on_exit"]
                for h in actions if isinstance(h, kinds["RegisterEventHandler"])}
    assert [type(a) for a in handlers["recorder"]] == [kinds["Shutdown"]]
    plant_exit = handlers["plant"]
    assert plant_exit(types.SimpleNamespace(returncode=0), None) == [], "the recorder still closes its bag"
    assert [type(a) for a in plant_exit(types.SimpleNamespace(returncode=3), None)] == [kinds["Shutdown"]]


def test_params_dir_when_given_is_started_instead(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "graph"
    assert main(["params", str(SCENARIO), "--out", str(folder)]) == 0
    kinds = fake_launch_api(monkeypatch)
    actions = load_launch_file().node_actions({"params_file": str(installed_params_file()), "params_dir": str(folder),
                                                "bag": ""})
    nodes = [a.kwargs for a in actions if isinstance(a, kinds["Node"])]
    assert [n["name"] for n in nodes] == ["plant", "interpolator", "servo_x", "servo_y", "servo_z"]
    assert nodes[2]["parameters"] == [str((folder / "servo_x.params.yaml").resolve())]


def test_a_graph_without_a_plant_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "servos.params.yaml"
    path.write_text(graph_params_yaml("/cnc", [("servo_x", {"axis": "x"})]))
    fake_launch_api(monkeypatch)
    with pytest.raises(ConfigError, match=r"a graph needs a plant node, got \['servo_x'\]"):
        load_launch_file().node_actions({"params_file": str(path), "params_dir": "", "bag": ""})


def test_with_the_real_launch_api_the_description_holds_the_nodes_and_the_shutdown_handler() -> None:
    launch_ros = pytest.importorskip("launch_ros.actions", reason="launch_ros has no PyPI wheels (system Jazzy only)")
    from launch import LaunchContext
    from launch.actions import RegisterEventHandler

    context = LaunchContext()
    context.launch_configurations.update({"params_file": str(installed_params_file()), "params_dir": "", "bag": ""})
    actions = load_launch_file().node_actions(context)
    assert sum(isinstance(a, launch_ros.Node) for a in actions) == 4
    assert sum(isinstance(a, RegisterEventHandler) for a in actions) == 1
