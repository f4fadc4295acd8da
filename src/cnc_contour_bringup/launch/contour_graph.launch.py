"""Launch a complete lockstep contour graph from one parameters file; the launch ends when the plant exits.

    ros2 launch cnc_contour_bringup contour_graph.launch.py                     # the installed default graph
    ros2 launch cnc_contour_bringup contour_graph.launch.py params_file:=FILE   # another graph file
    ros2 launch cnc_contour_bringup contour_graph.launch.py params_dir:=DIR     # a folder of `cnc-contour params`
    ros2 launch cnc_contour_bringup contour_graph.launch.py \
        params_file:=.../config/paper000_circle_high.recorded.params.yaml bag:=/tmp/circle_bag   # recorded
    ros2 launch cnc_contour_bringup contour_graph.launch.py managed:=true action:=true namespace:=/cell2

Arguments (:func:`launch_plan`, ROS-free and tested): ``managed:=true`` --
the interpolator, servos and plant wait unconfigured and a
``lifecycle_manager`` configures and then activates them (the plant last), as
``cnc-contour run --managed``; ``action:=true`` -- the interpolator takes
programs by RunProgram goal (``program_source: action``) and the plant's run
lasts ``ACTION_DURATION_S``; ``namespace:=/NS`` -- every node in ``/NS``
instead of the file's namespace (each gets its file's values as parameters,
as the file's sections are keyed by the old names); ``use_sim_time:=true`` --
every node but the plant (it publishes ``/clock``) runs on ``/clock``;
``record:=true`` / ``false`` -- the graph must (must not) have the recorder,
``true`` with no ``bag`` records to ``./cnc_contour_bag_<UTC time>``
(default: as the file says).

``params_file`` (default: ``share/cnc_contour_control/config/paper000_circle_high.params.yaml``,
paper 000's circle at 1.3 m/min) is one ROS 2 parameters file with a section
per node (``/cnc/plant``, ``/cnc/interpolator``, ``/cnc/servo_x``, ...) and
``/**`` for values they share (:mod:`cnc_contour_control.graph.graph_params`); its
sections are the nodes started, each with that file, in its folder (the
program it names is relative to it). The installed files are generated from
scenarios by the runner's code (``cnc-contour config-files``), so the launched
graph and ``cnc-contour run scenarios/paper000_circle_high.yaml`` start the
same nodes with the same values. ``params_dir``, when given, is used instead:
a folder written by ``cnc-contour params SCENARIO --out DIR`` (``graph.yaml``
and a file per node, the runner's files).

When the plant exits (the run is over, or it faulted) the launch shuts down
(``OnProcessExit`` -> ``Shutdown``), stopping the other nodes. A graph with
the suite's recorder (``*.recorded.params.yaml``; every stage waits for it)
writes its bag to ``bag:=DIR`` and ends when the recorder has closed it, or
at once when the plant fails. Each stage waits only for the readers its file
counts: record with ``ros2 bag record`` only what counted one
(``cnc-contour params --extra-subscribers 1``).

Without the ``ros2`` command line (PyPI wheels), ``cnc-contour run <scenario.yaml>``
starts the same executables with the same values, and the README's "By hand"
section starts them from the installed file. ``launch`` is imported only inside
the functions that build actions, so :func:`graph_nodes` (what this file starts)
can be read and tested where ``launch`` is not installed.
"""
from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import yaml

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.graph.graph_files import GraphNode, read_manifest
from cnc_contour_control.graph.graph_params import read_graph_params

PACKAGE = "cnc_contour_control"
#: The installed default graph, in ``share/<PACKAGE>/config/``.
DEFAULT_PARAMS_FILE = "paper000_circle_high.params.yaml"
#: The node whose exit ends the launch: it owns time and ends the run.
MAIN_NODE = "plant"
#: A graph's recorder: it gets its bag folder from the ``bag`` argument, and its exit ends the launch.
RECORDER = "recorder"
#: The executables whose nodes are lifecycle nodes, in the order the manager brings them up (the plant last), as
#: the runner's (cnc_tools.runs.managed.MANAGED_ORDER: the launch must not need cnc_tools importable).
MANAGED_ORDER = (("cnc_contour_control", "interpolator"), ("cnc_contour_control", "servo"), ("cnc_plant_sim", "plant"))
#: The plant's run in action mode, s (the bound of its ``duration_s``): goals come for as long as the graph is up.
ACTION_DURATION_S = 1.0e6
#: The launch arguments of :func:`launch_plan` with their defaults (``record`` empty: as the graph says).
ARGUMENTS = {"managed": "false", "action": "false", "namespace": "", "use_sim_time": "false", "record": "",
             "bag": ""}
#: The launch arguments' descriptions.
ARGUMENT_HELP = {
    "managed": "true: lifecycle nodes wait unconfigured; a lifecycle_manager configures, then activates them",
    "action": "true: the interpolator takes programs by RunProgram goal (program_source: action)",
    "namespace": "every node in this namespace instead of the parameters file's (e.g. /cell2)",
    "use_sim_time": "true: every node but the plant (it publishes /clock) runs on /clock",
    "record": "true: the graph must have the recorder (a *.recorded.params.yaml); false: must not; empty: as it is",
    "bag": "the bag folder of a graph with a recorder (must not exist)",
}


class LaunchNode(NamedTuple):
    """One process the launch starts: ``parameters`` as launch_ros takes them (file names and dicts).

    (A NamedTuple, not a dataclass: ``ros2 launch`` loads this file without registering it as a module.)
    """

    package: str
    executable: str
    name: str
    namespace: str
    parameters: list[Any]
    cwd: str = ""


def flag(name: str, value: str) -> bool:
    """A boolean launch argument: ``true`` or ``false`` (any case), else a ConfigError naming it and the value."""
    word = str(value).strip().lower()
    if word not in ("true", "false"):
        raise ConfigError(f"launch argument {name} must be true or false, got {value!r}")
    return word == "true"


def launch_plan(nodes: Sequence[GraphNode], arguments: Mapping[str, str],
                now_s: float | None = None) -> list[LaunchNode]:
    """The processes to start for ``nodes`` under the launch ``arguments`` (:data:`ARGUMENTS`; ROS-free)."""
    args = {**ARGUMENTS, **{k: str(v) for k, v in arguments.items()}}
    unknown = sorted(set(args) - set(ARGUMENTS))
    if unknown:
        raise ConfigError(f"unknown launch arguments {unknown}; known: {sorted(ARGUMENTS)}")
    managed, action, sim_time = (flag(name, args[name]) for name in ("managed", "action", "use_sim_time"))
    namespace = args["namespace"].strip()
    if namespace and not namespace.startswith("/"):
        raise ConfigError(f"launch argument namespace must be absolute (start with /), got {namespace!r}")
    names = [node.name for node in nodes]
    if MAIN_NODE not in names:
        raise ConfigError(f"a graph needs a {MAIN_NODE} node, got {sorted(names)}")
    bag = _bag(RECORDER in names, args["record"], args["bag"], time.time() if now_s is None else now_s)
    rank = {key: k for k, key in enumerate(MANAGED_ORDER)}
    plan = []
    for node in nodes:
        extra: dict[str, Any] = {}
        if managed and (node.package, node.executable) in rank:
            extra["managed"] = True
        if action and node.executable == "interpolator":
            extra.update(program_source="action", program_file="")
        if action and node.name == MAIN_NODE:
            extra["duration_s"] = ACTION_DURATION_S
        if sim_time and node.name != MAIN_NODE:
            extra["use_sim_time"] = True
        if node.name == RECORDER:
            extra["output"] = bag
        files: list[Any] = [file_values(node)] if namespace else [str(node.parameters_file)]
        plan.append(LaunchNode(node.package, node.executable, node.name, namespace or node.namespace,
                               [*files, *([extra] if extra else [])], str(node.parameters_file.parent)))
    if managed:
        lifecycle = sorted((n for n in nodes if (n.package, n.executable) in rank),
                           key=lambda n: rank[(n.package, n.executable)])
        plan.append(LaunchNode("cnc_tools", "lifecycle_manager", "lifecycle_manager",
                               namespace or nodes[names.index(MAIN_NODE)].namespace,
                               [{"node_names": [n.name for n in lifecycle]}]))
    return plan


def _bag(recorded: bool, record: str, bag: str, now_s: float) -> str:
    """The recorder's bag folder (empty without a recorder); ``record`` checked against the graph."""
    wanted = recorded if not record.strip() else flag("record", record)
    if wanted != recorded:
        raise ConfigError(f"launch argument record:={record} but the graph has {'a' if recorded else 'no'} recorder "
                          f"(record with params_file:=...recorded.params.yaml, or leave record empty)")
    if not recorded:
        return ""
    if bag:
        return bag
    if wanted and record.strip():
        return str(Path.cwd() / time.strftime("cnc_contour_bag_%Y%m%d_%H%M%S", time.gmtime(now_s)))
    raise ConfigError("the graph records; give the bag folder: bag:=DIR (must not exist), or record:=true")


def file_values(node: GraphNode) -> dict[str, Any]:
    """The node's values in its parameters file (``/**`` and its own section), flat (``gains.kp``)."""
    sections = yaml.safe_load(node.parameters_file.read_text()) or {}
    values: dict[str, Any] = {}
    for key in ("/**", node.full_name):
        values.update(_flat((sections.get(key) or {}).get("ros__parameters") or {}))
    return values


def _flat(mapping: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in mapping.items():
        if isinstance(value, Mapping):
            out.update(_flat(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def graph_nodes(params: str | Path) -> list[GraphNode]:
    """The nodes to start: a graph parameters file's sections, or a ``cnc-contour params`` folder's list."""
    path = Path(params)
    return read_manifest(path) if path.is_dir() else read_graph_params(path)


def chosen_params(params_file: str, params_dir: str) -> str:
    """``params_dir`` if given, else ``params_file``."""
    return params_dir or params_file


def node_actions(context: Any) -> list[Any]:
    """One ``launch_ros`` Node per node of the chosen graph, and the handlers that end the launch with the run."""
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    source = chosen_params(LaunchConfiguration("params_file").perform(context),
                           LaunchConfiguration("params_dir").perform(context))
    arguments = {name: LaunchConfiguration(name, default=default).perform(context)
                 for name, default in ARGUMENTS.items()}
    try:
        plan = launch_plan(graph_nodes(source), arguments)
    except ConfigError as err:
        raise ConfigError(f"{source}: {err}") from err
    nodes = {node.name: Node(package=node.package, executable=node.executable, name=node.name,
                             namespace=node.namespace, parameters=node.parameters,
                             **({"cwd": node.cwd} if node.cwd else {}), output="screen")
             for node in plan}
    return [*nodes.values(), *shutdown_handlers(nodes)]


def shutdown_handlers(nodes: dict[str, Any]) -> list[Any]:
    """The launch ends when the plant exits; in a recorded graph when the recorder exits (its bag closed),
    or when the plant fails."""
    from launch.actions import RegisterEventHandler, Shutdown
    from launch.event_handlers import OnProcessExit

    if RECORDER not in nodes:
        return [RegisterEventHandler(OnProcessExit(
            target_action=nodes[MAIN_NODE], on_exit=[Shutdown(reason=f"{MAIN_NODE} exited: the run is over")]))]

    def plant_failed(event: Any, context: Any) -> list[Any]:
        """Shut down at once if the plant failed (a recorder may never see the run's end)."""
        code = event.returncode
        return [Shutdown(reason=f"{MAIN_NODE} exited with code {code}")] if code != 0 else []

    return [RegisterEventHandler(OnProcessExit(target_action=nodes[MAIN_NODE], on_exit=plant_failed)),
            RegisterEventHandler(OnProcessExit(
                target_action=nodes[RECORDER], on_exit=[Shutdown(reason=f"{RECORDER} exited: the bag is closed")]))]


def generate_launch_description() -> Any:
    """The ``params_file``, ``params_dir`` and :data:`ARGUMENTS` arguments and the graph's nodes, read when the launch
    runs."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.substitutions import PathJoinSubstitution
    from launch_ros.substitutions import FindPackageShare

    default = PathJoinSubstitution([FindPackageShare(PACKAGE), "config", DEFAULT_PARAMS_FILE])
    return LaunchDescription([
        DeclareLaunchArgument("params_file", default_value=default,
                              description="one ROS 2 parameters file of a whole graph (cnc-contour config-files)"),
        DeclareLaunchArgument("params_dir", default_value="",
                              description="instead: a folder written by `cnc-contour params` (graph.yaml)"),
        *(DeclareLaunchArgument(name, default_value=default, description=ARGUMENT_HELP[name])
          for name, default in ARGUMENTS.items()),
        OpaqueFunction(function=node_actions),
    ])
