"""The installed parameter files are what the runner's code makes of their scenarios, and every node reads them so.

The committed files (``src/<package>/config/``) must equal what
:mod:`cnc_tools.runs.installed_params` generates now, and the installed ones
(``share/<package>/config/``) must be them, so they cannot drift from the
nodes' parameters. Each node class, started as launch and the README's "By
hand" start it (``--ros-args -r __ns -r __node --params-file`` of the one file,
in its folder), declares exactly the values it declares when started with the
runner's own file for that node: the ``/**`` section gives no node a value it
would not get from the runner.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

import pytest
import rclpy
from rclpy.context import Context

from cnc_contour_control.graph.graph_files import GraphNode, write_params_file
from cnc_contour_control.graph.graph_params import read_graph_params
from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_plant_sim.nodes.plant_node import PlantNode
from cnc_tools.nodes.recorder_node import RecorderNode
from cnc_tools.runs.graph_nodes import NAMESPACE, NodeSpec, graph_nodes, recorder_spec
from cnc_tools.runs.installed_params import INSTALLED, config_dir, installed_files, stale_files, write_installed
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
DEFAULT = INSTALLED[0]
NODE_CLASSES = {"plant": PlantNode, "interpolator": InterpolatorNode, "servo": ServoNode, "recorder": RecorderNode}
#: The two parameters the installed file names differently from a run folder (installed_params' docstring).
RELOCATED = {"program_file", "summary_file", "output"}  # (and the bag folder, given at start)


def installed_share(package: str) -> Path:
    """``share/<package>/config`` of the installed package (AMENT_PREFIX_PATH, as launch's FindPackageShare)."""
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        folder = Path(prefix) / "share" / package / "config"
        if prefix and folder.is_dir():
            return folder
    raise AssertionError(f"share/{package}/config is not installed under AMENT_PREFIX_PATH: run ./dev setup")


def test_the_committed_files_are_what_the_code_generates_now() -> None:
    assert stale_files(ROOT) == [], "regenerate them: ./dev cnc-contour config-files"
    assert sorted(p.name for p in config_dir(DEFAULT, ROOT).glob("*.yaml")) == sorted(installed_files(DEFAULT, ROOT))


def test_the_installed_files_are_the_committed_ones() -> None:
    for entry in INSTALLED:
        share = installed_share(entry.package)
        for name in installed_files(entry, ROOT):
            assert (share / name).read_text() == (config_dir(entry, ROOT) / name).read_text(), name


def test_a_changed_scenario_makes_its_installed_files_stale(tmp_path: Path) -> None:
    (tmp_path / "scenarios").mkdir()
    scenario = tmp_path / "scenarios" / f"{DEFAULT.scenario}.yaml"
    shutil.copy(ROOT / "scenarios" / scenario.name, scenario)
    written = write_installed(tmp_path)
    assert stale_files(tmp_path) == []
    scenario.write_text(scenario.read_text().replace("kp: 2.4", "kp: 2.5"))
    assert stale_files(tmp_path) == [config_dir(DEFAULT, tmp_path) / name
                                     for name in (DEFAULT.params_file, DEFAULT.recorded_params_file)]
    written[0].unlink()
    assert written[0] in stale_files(tmp_path)


def test_the_default_graph_is_plant_interpolator_and_a_servo_per_axis() -> None:
    nodes = read_graph_params(installed_share(DEFAULT.package) / DEFAULT.params_file)
    assert [(n.name, n.package, n.executable, n.namespace) for n in nodes] == [
        ("plant", "cnc_plant_sim", "plant", NAMESPACE),
        ("interpolator", "cnc_contour_control", "interpolator", NAMESPACE),
        ("servo_x", "cnc_contour_control", "servo", NAMESPACE),
        ("servo_y", "cnc_contour_control", "servo", NAMESPACE)]


def runner_specs(recorded: bool, run_dir: Path) -> dict[str, NodeSpec]:
    """The nodes ``cnc-contour run`` starts for the default scenario (recording or not), their files in ``run_dir``."""
    scenario = load_scenario(ROOT / "scenarios" / f"{DEFAULT.scenario}.yaml")
    extra = [recorder_spec(scenario, run_dir / "bag")] if recorded else []
    specs = [*extra, *graph_nodes(scenario, run_dir, len(extra), extra_readers=[e.name for e in extra])]
    return {spec.name: spec for spec in specs}


@pytest.mark.nodes
@pytest.mark.parametrize("recorded", [False, True])
def test_every_node_declares_from_the_one_file_what_it_declares_from_the_runners_file(
        recorded: bool, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    share = installed_share(DEFAULT.package)
    runner = runner_specs(recorded, tmp_path)
    nodes = read_graph_params(share / (DEFAULT.recorded_params_file if recorded else DEFAULT.params_file))
    assert [node.name for node in nodes] == list(runner)
    for node in nodes:
        own = GraphNode(node.name, node.package, node.executable, node.namespace,
                        write_params_file(tmp_path, NAMESPACE, node.name, runner[node.name].parameters))
        monkeypatch.chdir(share)  # as launch and the README start them: in the file's folder
        from_file = declared(node, tmp_path / "file_bag")
        monkeypatch.chdir(tmp_path)
        from_runner = declared(own, tmp_path / "bag")
        assert set(from_file) == set(from_runner), node.name
        assert {k: v for k, v in from_file.items() if k not in RELOCATED} == \
            {k: v for k, v in from_runner.items() if k not in RELOCATED}, node.name
        assert len(from_runner) > 5, f"{node.name}: the runner's values were read"
    assert (share / DEFAULT.program_file).read_text() == (tmp_path / "program.yaml").read_text()


def declared(node: GraphNode, bag: Path) -> dict[str, Any]:
    """Every parameter the node class declares, started with ``--params-file`` of ``node.parameters_file``.

    The recorder, which creates its bag as it starts, gets ``-p output:=bag`` besides (the README's start).
    """
    output = ["-p", f"output:={bag}"] if node.executable == "recorder" else []
    context = Context()
    rclpy.init(context=context, args=["--ros-args", "-r", f"__ns:={node.namespace}", "-r", f"__node:={node.name}",
                                      "--params-file", str(node.parameters_file), *output])
    try:
        instance = NODE_CLASSES[node.executable](context=context)
        try:
            return {name: _plain(p.value) for name, p in instance.get_parameters_by_prefix("").items()}
        finally:
            instance.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def _plain(value: Any) -> Any:
    return value if value is None or isinstance(value, (str, bool, int, float)) else list(value)
