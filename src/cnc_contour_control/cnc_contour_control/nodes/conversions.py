"""Messages to arrays and back for the control nodes (the package's one conversions module)."""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NoReturn

from sensor_msgs.msg import JointState

from cnc_contour_control.axis.servo import ServoOutput
from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.core.lockstep import require_finite_values, require_same_axes
from cnc_contour_control.estimators import ContourEstimate
from cnc_contour_control.motion.geometry import ArcSegment, Program, Segment
from cnc_contour_control.motion.reference_types import ReferenceSample
from cnc_contour_control.nodes.common import ns_to_stamp, set_stamp
from cnc_contour_control.nodes.fast_cdr import constructor
from cnc_contour_interfaces.msg import AxisCommand, Compensation, ContourError, Path, PathSegment, Reference

#: New per-tick messages at their defaults, as ``Reference()`` and ``AxisCommand()`` give them (without their checks).
_new_reference = constructor(Reference)
_new_command = constructor(AxisCommand)


def reference_to_msg(sample: ReferenceSample, axes: Sequence[str], stamp_ns: int, frame_id: str) -> Reference:
    """A core reference sample to a Reference message."""
    msg = _new_reference()
    set_stamp(msg.header.stamp, stamp_ns)
    msg.header.frame_id = frame_id
    msg.axis_names = list(axes)
    msg.position_m = sample.position_m.tolist()
    msg.velocity_m_s = sample.velocity_m_s.tolist()
    msg.acceleration_m_s2 = sample.acceleration_m_s2.tolist()
    msg.path_length_m = float(sample.path_length_m)
    msg.segment_index = int(sample.segment_index)
    msg.feed_m_s = float(sample.feed_m_s)
    msg.programmed_feed_m_s = float(sample.programmed_feed_m_s)
    msg.feed_override_ratio = float(sample.feed_override_ratio)
    msg.done = bool(sample.done)
    return msg


#: A Reference's per-axis fields, with the names its faults give them.
_REFERENCE_AXIS_FIELDS = tuple((name, f"reference.{name}") for name in ("position_m", "velocity_m_s",
                                                                        "acceleration_m_s2"))


def reference_axis(msg: Reference, axis: str) -> tuple[float, float, float]:
    """Position, velocity, acceleration of one axis from a Reference; faults on bad data."""
    index = axis_index(msg.axis_names, axis, "reference")
    count = len(msg.axis_names)
    for name, field in _REFERENCE_AXIS_FIELDS:
        require_length(getattr(msg, name), count, field, "axis_names")
    values = (msg.position_m[index], msg.velocity_m_s[index], msg.acceleration_m_s2[index])
    if not _all_finite(values):  # the fault's wording only when there is one
        require_finite_values(values, f"reference[{axis}] (position_m, velocity_m_s, acceleration_m_s2)")
    return values


def _all_finite(values: tuple[float, ...]) -> bool:
    """True when no value is NaN or infinite (one sum: a NaN or an infinity makes it NaN)."""
    total = sum(values)
    return total - total == 0.0


def joint_positions(msg: JointState, axes: Sequence[str]) -> tuple[list[float], list[float]]:
    """Positions [m] and velocities [m/s] of ``axes`` from a JointState; faults on bad data."""
    require_same_axes(msg.name, axes, "joint_states")
    positions = list(msg.position)
    velocities = list(msg.velocity) if len(msg.velocity) else [0.0] * len(axes)
    if len(positions) != len(axes) or len(velocities) != len(axes):
        raise_missing_axis("joint_states", ",".join(axes), msg.name)
    require_finite_values(positions, "joint_states.position")
    require_finite_values(velocities, "joint_states.velocity")
    return positions, velocities


def joint_position(msg: JointState, axis: str) -> float:
    """Position [m] of one axis from a JointState; faults on bad data."""
    index = axis_index(msg.name, axis, "joint_states")
    require_length(msg.position, len(msg.name), "joint_states.position", "name")
    value = msg.position[index]
    if not _all_finite((value,)):
        require_finite_values((value,), f"joint_states.position[{axis}]")
    return float(value)


def joint_velocity(msg: JointState, axis: str) -> float:
    """Velocity [m/s] of one axis from a JointState (0 when the message carries no velocities); faults on bad data."""
    index = axis_index(msg.name, axis, "joint_states")
    if not len(msg.velocity):
        return 0.0
    require_length(msg.velocity, len(msg.name), "joint_states.velocity", "name")
    value = msg.velocity[index]
    if not _all_finite((value,)):
        require_finite_values((value,), f"joint_states.velocity[{axis}]")
    return float(value)


def require_length(values: Sequence[float], count: int, field: str, names_field: str) -> None:
    """Fault: a per-axis array field does not hold one value per axis name."""
    if len(values) != count:
        raise FaultError(f"{field} has {len(values)} values for {count} {names_field}")


def axis_index(names: Sequence[str], axis: str, what: str) -> int:
    """Index of ``axis`` among a message's axis names; faults when it is missing or named twice."""
    present = list(names)
    if axis not in present:
        raise_missing_axis(what, axis, present)
    if present.count(axis) > 1:
        raise FaultError(f"{what} names axis {axis!r} {present.count(axis)} times (axes present: {present}): "
                         "which value is meant is unknown")
    return present.index(axis)


def raise_missing_axis(what: str, axis: str, present: Sequence[str]) -> NoReturn:
    """Fault: a message lacks an axis."""
    raise FaultError(f"{what} has no axis {axis!r} (axes present: {list(present)})")


def command_to_msg(output: ServoOutput, axis: str, law: str, unit: str, stamp_ns: int) -> AxisCommand:
    """A core servo output to an AxisCommand message."""
    msg = _new_command()
    set_stamp(msg.header.stamp, stamp_ns)
    msg.header.frame_id = axis
    msg.axis_name = axis
    msg.law = law
    msg.command_unit = unit
    msg.command = float(output.command)
    msg.feedback = float(output.feedback)
    msg.feedforward = float(output.feedforward)
    msg.compensation = float(output.compensation)
    msg.disturbance_estimate = float(output.disturbance_estimate)
    msg.saturated = bool(output.saturated)
    msg.error_m = float(output.error_m)
    return msg


def program_to_path(program: Program, stamp_ns: int, frame_id: str, duration_s: float) -> Path:
    """A core program to a Path message; its ``path_tolerance_m`` (None: NaN, not known) as the message's."""
    msg = Path()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = frame_id
    msg.program_name = program.name
    msg.axis_names = list(program.axis_names)
    msg.segments = [_segment_msg(segment) for segment in program.segments]
    msg.total_length_m = float(program.total_length_m)
    msg.planned_duration_s = float(duration_s)
    msg.path_tolerance_m = math.nan if program.path_tolerance_m is None else float(program.path_tolerance_m)
    return msg


def _segment_msg(segment: Segment) -> PathSegment:
    msg = PathSegment()
    msg.start_m = [float(v) for v in segment.start_m]
    msg.end_m = [float(v) for v in segment.end_m]
    msg.feed_m_s = float(segment.feed_m_s)
    msg.length_m = float(segment.length_m)
    if isinstance(segment, ArcSegment):
        msg.kind = PathSegment.ARC_CW if segment.clockwise else PathSegment.ARC_CCW
        msg.center_m = [float(v) for v in segment.center_m]
        msg.plane_axes = list(segment.plane)
    else:
        msg.kind = PathSegment.LINE
        msg.plane_axes = [0, 1]
    return msg


def compensation_for(msg: Any, axis: str) -> float:
    """The correction of one axis from a Compensation message; faults on bad data."""
    names = list(msg.axis_names)
    index = axis_index(names, axis, "compensation")
    require_length(msg.correction, len(names), "compensation.correction", "axis_names")
    value = float(msg.correction[index])
    require_finite_values((value,), f"compensation.correction[{axis}]")
    return value


def reference_positions(msg: Reference, axes: Sequence[str]) -> list[float]:
    """Reference positions [m] of ``axes`` (in that order) from a Reference; faults on bad data."""
    require_same_axes(msg.axis_names, axes, "reference")
    require_length(msg.position_m, len(msg.axis_names), "reference.position_m", "axis_names")
    values = [float(v) for v in msg.position_m]  # the axes are ours, in our order
    require_finite_values(values, "reference.position_m")
    return values


def estimate_to_msg(estimate: ContourEstimate, axes: Sequence[str], stamp_ns: int, method: str) -> ContourError:
    """A core contour-error estimate to a ContourError message."""
    msg = ContourError()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.axis_names = list(axes)
    msg.contour_error_m = float(estimate.contour_error_m)
    msg.tracking_error_m = [float(v) for v in estimate.tracking_error_m]
    msg.segment_index = int(estimate.segment_index)
    msg.angle_rad = float(estimate.angle_rad)
    msg.point_a_m = [float(v) for v in estimate.point_a_m]
    msg.point_b_m = [float(v) for v in estimate.point_b_m]
    msg.window_size = int(estimate.window_size)
    msg.window_steps = int(estimate.steps)
    msg.method = method
    return msg


def contour_error_values(msg: ContourError, axes: Sequence[str]) -> tuple[float, float, list[float]]:
    """(contour error [m], tangent angle [rad], tracking errors [m] in ``axes`` order) from a ContourError."""
    require_same_axes(msg.axis_names, axes, "contour_error")
    require_length(msg.tracking_error_m, len(msg.axis_names), "contour_error.tracking_error_m", "axis_names")
    tracking = [float(v) for v in msg.tracking_error_m]  # the axes are ours, in our order
    require_finite_values((msg.contour_error_m, msg.angle_rad), "contour_error (contour_error_m, angle_rad)")
    require_finite_values(tracking, "contour_error.tracking_error_m")
    return float(msg.contour_error_m), float(msg.angle_rad), tracking


def compensation_to_msg(correction: Sequence[float], axes: Sequence[str], unit: str, stamp_ns: int, method: str,
                        learning: bool) -> Compensation:
    """Per-axis corrections to a Compensation message."""
    msg = Compensation()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.axis_names = list(axes)
    msg.correction = [float(v) for v in correction]
    msg.command_unit = unit
    msg.method = method
    msg.learning = bool(learning)
    return msg
