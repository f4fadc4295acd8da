"""Tier 1: the launch file's arguments (managed, action, namespace, use_sim_time, record) as :func:`launch_plan` reads
them: which processes start with which parameters (ROS-free: ``launch`` has no wheels here)."""
from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import pytest

from cnc_contour_control.core.errors import ConfigError

LAUNCH_FILE = Path(__file__).resolve().parents[2] / "cnc_contour_bringup" / "launch" / "contour_graph.launch.py"
CONFIG = Path(__file__).resolve().parents[2] / "cnc_contour_control" / "config"
PLAIN, RECORDED = CONFIG / "paper000_circle_high.params.yaml", CONFIG / "paper000_circle_high.recorded.params.yaml"


def load_launch_file() -> Any:
    spec = importlib.util.spec_from_file_location("contour_graph_launch_arguments", LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]  # the file exists: a spec
    spec.loader.exec_module(module)  # type: ignore[union-attr]  # a source file's spec has a loader
    return module


LAUNCH = load_launch_file()


def plan(params_file: Path = PLAIN, **arguments: str) -> dict[str, Any]:
    return {node.name: node for node in LAUNCH.launch_plan(LAUNCH.graph_nodes(params_file), arguments, now_s=0.0)}


def test_the_defaults_start_the_files_nodes_with_the_file_alone() -> None:
    nodes = plan()
    assert list(nodes) == ["plant", "interpolator", "servo_x", "servo_y"]
    assert all(n.parameters == [str(PLAIN.resolve())] and n.namespace == "/cnc" for n in nodes.values())


def test_managed_adds_the_manager_in_the_runners_order_and_action_takes_goals() -> None:
    nodes = plan(managed="true", action="True")
    manager = nodes["lifecycle_manager"]
    assert (manager.package, manager.executable, manager.namespace) == ("cnc_tools", "lifecycle_manager", "/cnc")
    assert manager.parameters == [{"node_names": ["interpolator", "servo_x", "servo_y", "plant"]}]
    assert nodes["servo_x"].parameters[1] == {"managed": True}
    assert nodes["interpolator"].parameters[1] == {"managed": True, "program_source": "action", "program_file": ""}
    assert nodes["plant"].parameters[1] == {"managed": True, "duration_s": LAUNCH.ACTION_DURATION_S}


def test_a_namespace_moves_every_node_with_its_files_values_and_sim_time_spares_the_plant() -> None:
    nodes = plan(namespace="/cell2", use_sim_time="true")
    assert {n.namespace for n in nodes.values()} == {"/cell2"}
    servo = nodes["servo_x"].parameters
    assert servo[0]["gains.kp"] == 2.4 and servo[0]["axis"] == "x" and servo[1] == {"use_sim_time": True}
    assert nodes["plant"].parameters[0]["model"] == "paper000" and len(nodes["plant"].parameters) == 1


def test_record_true_records_to_a_dated_bag_and_must_match_the_graph() -> None:
    recorder = plan(RECORDED, record="true")["recorder"]
    assert recorder.parameters[1]["output"].endswith("cnc_contour_bag_19700101_000000")
    assert plan(RECORDED, bag="/tmp/b")["recorder"].parameters[1] == {"output": "/tmp/b"}
    with pytest.raises(ConfigError, match="record:=true but the graph has no recorder"):
        plan(record="true")
    with pytest.raises(ConfigError, match="record:=false but the graph has a recorder"):
        plan(RECORDED, record="false")


@pytest.mark.parametrize(("arguments", "message"), [
    ({"managed": "yes"}, "launch argument managed must be true or false, got 'yes'"),
    ({"namespace": "cell2"}, "launch argument namespace must be absolute"),
    ({"manged": "true"}, r"unknown launch arguments \['manged'\]"),
])
def test_a_bad_argument_is_refused_naming_it_and_the_value(arguments: dict[str, str], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        LAUNCH.launch_plan(LAUNCH.graph_nodes(PLAIN), arguments)
