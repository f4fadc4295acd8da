"""Synthetic programs, runs and bags with known errors: for tests, benchmarks and demonstrations (ROS-free)."""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.typesys.store import Typestore

from cnc_contour_control.core.lockstep import seconds_to_ns, split_ns
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment, Program
from cnc_tools.bagio.bag import BagIntegrity, BagWriter, JointStateSeries, RecordedRun, ReferenceSeries
from cnc_tools.bagio.typestore import project_typestore

NS = "/cnc"
TOPICS = {
    f"{NS}/path": "cnc_contour_interfaces/msg/Path",
    f"{NS}/joint_states": "sensor_msgs/msg/JointState",
    f"{NS}/reference": "cnc_contour_interfaces/msg/Reference",
    "/clock": "rosgraph_msgs/msg/Clock",
}
COMMAND_TYPE = "cnc_contour_interfaces/msg/AxisCommand"


def circle_program(radius_m: float = 0.02, feed_m_s: float = 0.01, n_axes: int = 2,
                   clockwise: bool = False) -> Program:
    """A full circle about the origin starting at (R, 0[, 0])."""
    start = np.zeros(n_axes)
    start[0] = radius_m
    arc = ArcSegment(start_m=start, end_m=start, center_m=np.zeros(n_axes), clockwise=clockwise,
                     plane=(0, 1), feed_m_s=feed_m_s)
    return Program(name="circle", axis_names=("x", "y", "z")[:n_axes], segments=(arc,))


def corner_program(side_m: float = 0.01, feed_m_s: float = 0.01) -> Program:
    """Two lines meeting at a right angle: (0,0) -> (side,0) -> (side,side)."""
    a, b, c = np.array([0.0, 0.0]), np.array([side_m, 0.0]), np.array([side_m, side_m])
    return Program(name="corner", axis_names=("x", "y"),
                   segments=(LineSegment(start_m=a, end_m=b, feed_m_s=feed_m_s),
                             LineSegment(start_m=b, end_m=c, feed_m_s=feed_m_s)))


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Synthetic run data: stamps (N,) ns, positions and references (N, n_axes) m, ref velocity m/s."""

    stamp_ns: NDArray[np.int64]
    position_m: NDArray[np.float64]
    reference_m: NDArray[np.float64]
    reference_velocity_m_s: NDArray[np.float64]


def circle_trajectory(radius_m: float, offset_m: float, n: int = 2000, dt_s: float = 1e-3, n_axes: int = 2,
                      lag_rad: float = 0.0) -> Trajectory:
    """One CCW revolution: reference on the circle, position at radius R + offset, lagging by ``lag_rad``."""
    theta = np.linspace(0.0, 2 * np.pi, n)
    omega = 2 * np.pi / ((n - 1) * dt_s)
    reference = np.zeros((n, n_axes))
    reference[:, 0], reference[:, 1] = radius_m * np.cos(theta), radius_m * np.sin(theta)
    velocity = np.zeros((n, n_axes))
    velocity[:, 0], velocity[:, 1] = -radius_m * omega * np.sin(theta), radius_m * omega * np.cos(theta)
    position = np.zeros((n, n_axes))
    position[:, 0] = (radius_m + offset_m) * np.cos(theta - lag_rad)
    position[:, 1] = (radius_m + offset_m) * np.sin(theta - lag_rad)
    stamps = (np.arange(n, dtype=np.int64) + 1) * seconds_to_ns(dt_s, "dt_s")
    return Trajectory(stamps, position, reference, velocity)


def path_message(program: Program) -> object:
    """A cnc_contour_interfaces/msg/Path (rosbags object) describing ``program``."""
    types = project_typestore().types
    segment_type = types["cnc_contour_interfaces/msg/PathSegment"]
    segments = []
    seg: Any  # a line or an arc: the arc's fields are read only where is_arc
    for seg in program.segments:
        is_arc = isinstance(seg, ArcSegment)
        segments.append(segment_type(
            kind=(1 if seg.clockwise else 2) if is_arc else 0, start_m=np.asarray(seg.start_m, float),
            end_m=np.asarray(seg.end_m, float),
            center_m=np.asarray(seg.center_m, float) if is_arc else np.zeros(0),
            plane_axes=np.asarray(seg.plane if is_arc else (0, 1), dtype=np.uint8),
            feed_m_s=float(seg.feed_m_s), length_m=float(seg.length_m)))
    return types["cnc_contour_interfaces/msg/Path"](
        header=header(0, "machine"), program_name=program.name, axis_names=list(program.axis_names),
        segments=segments, total_length_m=float(program.total_length_m), planned_duration_s=1.0,
        path_tolerance_m=math.nan if program.path_tolerance_m is None else float(program.path_tolerance_m))


def header(stamp_ns: int, frame_id: str) -> Any:
    types = project_typestore().types
    sec, nanosec = split_ns(stamp_ns)
    stamp = types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
    return types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)


def joint_state(stamp_ns: int, names: Sequence[str], position: np.ndarray, velocity: np.ndarray) -> object:
    return project_typestore().types["sensor_msgs/msg/JointState"](
        header=header(stamp_ns, "machine"), name=list(names), position=np.asarray(position, float),
        velocity=np.asarray(velocity, float), effort=np.zeros(0))


def reference(stamp_ns: int, names: Sequence[str], position: np.ndarray, velocity: np.ndarray,
              path_length_m: float = 0.0, done: bool = False) -> object:
    return project_typestore().types["cnc_contour_interfaces/msg/Reference"](
        header=header(stamp_ns, "machine"), axis_names=list(names), position_m=np.asarray(position, float),
        velocity_m_s=np.asarray(velocity, float), acceleration_m_s2=np.zeros(len(names)),
        path_length_m=path_length_m, segment_index=0, feed_m_s=0.01, programmed_feed_m_s=0.01,
        feed_override_ratio=1.0, done=done)


def axis_command(stamp_ns: int, axis: str, command: float, error_m: float) -> object:
    return project_typestore().types[COMMAND_TYPE](
        header=header(stamp_ns, axis), axis_name=axis, law="pid", command_unit="dac", command=command,
        feedback=command, feedforward=0.0, compensation=0.0, disturbance_estimate=0.0,
        saturated=abs(command) >= 127.0, error_m=error_m)


def write_run_bag(path: Path, program: Program, traj: Trajectory, *, commands: bool = True,
                  joint_names: Sequence[str] | None = None, with_path: bool = True,
                  typestore: Typestore | None = None) -> Path:
    """Record a synthetic run in a bag: path, joint_states, reference, clock, and per-axis commands.

    ``typestore`` gives the schemas the bag records (default the project's): another one writes a bag as an
    older or newer suite would have (fields it lacks are left out).
    """
    axes = list(program.axis_names)
    names = list(joint_names) if joint_names is not None else axes
    topics = dict(TOPICS)
    if not with_path:
        del topics[f"{NS}/path"]
    if commands:
        topics.update({f"{NS}/servo/{a}/command": COMMAND_TYPE for a in axes})
    clock_type = project_typestore().types["rosgraph_msgs/msg/Clock"]
    with BagWriter(path, topics, typestore=typestore) as writer:
        if with_path:
            writer.write_message(f"{NS}/path", 0, path_message(program))
        for k, stamp in enumerate(traj.stamp_ns.tolist()):
            writer.write_message("/clock", stamp, clock_type(clock=header(stamp, "").stamp))
            index = [axes.index(n) if n in axes else 0 for n in names]
            writer.write_message(f"{NS}/joint_states", stamp,
                                 joint_state(stamp, names, traj.position_m[k, index],
                                             traj.reference_velocity_m_s[k, index]))
            writer.write_message(f"{NS}/reference", stamp,
                                 reference(stamp, axes, traj.reference_m[k], traj.reference_velocity_m_s[k],
                                           done=k == len(traj.stamp_ns) - 1))
            for j, axis in enumerate(axes if commands else ()):
                error = float(traj.reference_m[k, j] - traj.position_m[k, j])
                writer.write_message(f"{NS}/servo/{axis}/command", stamp, axis_command(stamp, axis, 1e5 * error, error))
    return path


def make_run(program: Program, traj: Trajectory, *, name: str = "synthetic", reference_from: int = 0,
             integrity: BagIntegrity | None = None) -> RecordedRun:
    """A RecordedRun built in memory; the reference starts at sample ``reference_from``."""
    n = traj.stamp_ns.size
    ref = slice(reference_from, n)
    reference_series = ReferenceSeries(
        traj.stamp_ns[ref], traj.reference_m[ref], traj.reference_velocity_m_s[ref],
        np.zeros_like(traj.reference_m[ref]), np.zeros(n - reference_from), np.zeros(n - reference_from, np.int64),
        np.full(n - reference_from, 0.01), np.zeros(n - reference_from, bool))
    found = {"/cnc/joint_states": n, "/cnc/reference": n - reference_from, "/cnc/path": 1}
    return RecordedRun(
        name=name, source=Path(name), program=program,
        joint_states=JointStateSeries(traj.stamp_ns, traj.position_m, traj.reference_velocity_m_s),
        reference=reference_series, commands={},
        integrity=integrity or BagIntegrity(True, "index", found, found, "metadata.yaml"))


def offset_trajectory(program: Program, normal_offsets_m: Sequence[float], n_per_segment: int = 200,
                      dt_s: float = 1e-3) -> Trajectory:
    """Samples strictly inside each planar segment, displaced by a known distance along the left normal (XY)."""
    points, refs, vels = [], [], []
    for seg, offset in zip(program.segments, normal_offsets_m):
        s = np.linspace(0.0, seg.length_m, n_per_segment + 2)[1:-1]
        tangent = seg.tangent(s)
        normal = np.zeros_like(tangent)
        normal[:, 0], normal[:, 1] = -tangent[:, 1], tangent[:, 0]
        refs.append(seg.point(s))
        points.append(seg.point(s) + offset * normal)
        vels.append(tangent * seg.feed_m_s)
    position = np.concatenate(points)
    stamps = (np.arange(position.shape[0], dtype=np.int64) + 1) * seconds_to_ns(dt_s, "dt_s")
    return Trajectory(stamps, position, np.concatenate(refs), np.concatenate(vels))
