"""Launch the lockstep contour graph (plant, interpolator, one servo per axis) for ROS 2 users.

    ros2 launch cnc_contour_control contour_graph.launch.py program_file:=/path/program.yaml

Without the ``ros2`` CLI (PyPI wheels), use ``cnc-contour run <scenario.yaml>``, which starts
the same executables with a parameters file per node.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    """Plant, interpolator and an X and a Y servo in namespace /cnc."""
    program = LaunchConfiguration("program_file")
    period = LaunchConfiguration("sample_time_s")
    servos = [
        Node(package="cnc_contour_control", executable="servo", name=f"servo_{axis}", namespace="cnc",
             parameters=[{"axis": axis, "sample_time_s": period}])
        for axis in ("x", "y")
    ]
    return LaunchDescription([
        DeclareLaunchArgument("program_file", description="YAML program or G-code file"),
        DeclareLaunchArgument("sample_time_s", default_value="0.01"),
        DeclareLaunchArgument("duration_s", default_value="10.0"),
        Node(package="cnc_plant_sim", executable="plant", name="plant", namespace="cnc",
             parameters=[{"sample_time_s": period, "duration_s": LaunchConfiguration("duration_s"),
                          "expected_subscribers": 3}]),
        Node(package="cnc_contour_control", executable="interpolator", name="interpolator", namespace="cnc",
             parameters=[{"program_file": program, "min_subscribers": 2}]),
        *servos,
    ])
