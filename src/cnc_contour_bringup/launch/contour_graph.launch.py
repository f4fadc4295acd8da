"""Launch a complete lockstep contour graph from one parameters file; the launch ends when the plant exits.

    ros2 launch cnc_contour_bringup contour_graph.launch.py                     # the installed default graph
    ros2 launch cnc_contour_bringup contour_graph.launch.py params_file:=FILE   # another graph file
    ros2 launch cnc_contour_bringup contour_graph.launch.py params_dir:=DIR     # a folder of `cnc-contour params`
    ros2 launch cnc_contour_bringup contour_graph.launch.py \
        params_file:=.../config/paper000_circle_high.recorded.params.yaml bag:=/tmp/circle_bag   # recorded

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

from pathlib import Path
from typing import Any

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


def graph_nodes(params: str | Path) -> list[GraphNode]:
    """The nodes to start: a graph parameters file's sections, or a ``cnc-contour params`` folder's list."""
    path = Path(params)
    return read_manifest(path) if path.is_dir() else read_graph_params(path)


def chosen_params(params_file: str, params_dir: str) -> str:
    """``params_dir`` if given, else ``params_file``."""
    return params_dir or params_file


def node_parameters(node: GraphNode, bag: str) -> list[Any]:
    """The node's parameters file, and for the recorder its bag folder (a ConfigError without one)."""
    if node.name != RECORDER:
        return [str(node.parameters_file)]
    if not bag:
        raise ConfigError(f"{node.parameters_file}: the graph records; give the bag folder: bag:=DIR (must not exist)")
    return [str(node.parameters_file), {"output": bag}]


def node_actions(context: Any) -> list[Any]:
    """One ``launch_ros`` Node per node of the chosen graph, and the handlers that end the launch with the run."""
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    source = chosen_params(LaunchConfiguration("params_file").perform(context),
                           LaunchConfiguration("params_dir").perform(context))
    bag = LaunchConfiguration("bag").perform(context)
    nodes = {node.name: Node(package=node.package, executable=node.executable, name=node.name,
                             namespace=node.namespace, parameters=node_parameters(node, bag),
                             cwd=str(node.parameters_file.parent), output="screen")
             for node in graph_nodes(source)}
    if MAIN_NODE not in nodes:
        raise ConfigError(f"{source}: a graph needs a {MAIN_NODE} node, got {sorted(nodes)}")
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
    """The ``params_file``, ``params_dir`` and ``bag`` arguments and the graph's nodes, read when the launch runs."""
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
        DeclareLaunchArgument("bag", default_value="",
                              description="the bag folder of a graph with a recorder (must not exist)"),
        OpaqueFunction(function=node_actions),
    ])
