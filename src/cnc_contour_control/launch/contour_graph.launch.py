"""Launch a scenario's lockstep contour graph for ROS 2 users, with the runner's own parameter files.

    cnc-contour params scenarios/paper000_circle_high.yaml --out /tmp/circle
    ros2 launch cnc_contour_control contour_graph.launch.py params_dir:=/tmp/circle

``params_dir`` is a folder written by ``cnc-contour params``: ``graph.yaml``
lists the nodes (plant, interpolator, one servo per axis: the scenario's stage
pipeline) and each node has its parameters file there, the same files the
runner starts its processes with. (A run folder of ``cnc-contour run`` is not
one: it lists the run's recorder, whose bag folder exists already.)
Each stage waits for its readers before it publishes: record with
``ros2 bag record`` or add a reader by hand only if the folder counted it
(``cnc-contour params --extra-subscribers N``).

Without the ``ros2`` command line (PyPI wheels), ``cnc-contour run <scenario.yaml>``
starts the same executables with the same files. ``launch`` is imported only
inside :func:`generate_launch_description`, so :func:`graph_nodes` (what this
file starts) can be read and tested where ``launch`` is not installed.
"""
from __future__ import annotations

from typing import Any

from cnc_contour_control.graph_files import GraphNode, read_manifest


def graph_nodes(params_dir: str) -> list[GraphNode]:
    """The nodes to start from ``params_dir``: package, executable, name, namespace, parameters file."""
    return read_manifest(params_dir)


def node_actions(context: Any) -> list[Any]:
    """One ``launch_ros`` Node per node of the folder named by the ``params_dir`` argument."""
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    folder = LaunchConfiguration("params_dir").perform(context)
    return [Node(package=node.package, executable=node.executable, name=node.name, namespace=node.namespace,
                 parameters=[str(node.parameters_file)], output="screen")
            for node in graph_nodes(folder)]


def generate_launch_description() -> Any:
    """The ``params_dir`` argument and the graph's nodes, read from it when the launch runs."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction

    return LaunchDescription([
        DeclareLaunchArgument("params_dir", description="folder written by `cnc-contour params`"),
        OpaqueFunction(function=node_actions),
    ])
