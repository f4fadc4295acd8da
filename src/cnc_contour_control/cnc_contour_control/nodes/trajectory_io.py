"""A servo's trajectory_msgs/JointTrajectory input: the message to one axis's points for the core follower.

The trajectory comes from outside the lockstep loop (a planner): one that
cannot be followed (a missing joint, ragged points, NaN, a stale or future
stamp) is refused, counted and reported on ``/diagnostics``
(:class:`~cnc_contour_control.nodes.refusals.RefusalCounter`); the servo keeps
the trajectory it had and the machine goes on.
"""
from __future__ import annotations

from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from cnc_contour_control.core.errors import CncError, FaultError
from cnc_contour_control.core.lockstep import NS_PER_S
from cnc_contour_control.motion.trajectory_reference import TrajectoryFollower
from cnc_contour_control.nodes.common import SuiteNode, stamp_to_ns
from cnc_contour_control.nodes.refusals import RefusalCounter

#: A planner publishes a trajectory once: reliable, volatile (matches any reliable writer), a few kept.
TRAJECTORY_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.VOLATILE)


def trajectory_points(msg: Any, axis: str) -> tuple[int, list[float], list[float], list[float] | None]:
    """(start stamp [ns], times [s], positions [m], velocities [m/s] or None) of ``axis`` from a JointTrajectory.

    Velocities count only when every point carries one per joint; a FaultError names the missing joint or field.
    """
    names = list(msg.joint_names)
    if axis not in names:
        raise FaultError(f"joint_trajectory has no joint {axis!r} (joint_names: {names})")
    index = names.index(axis)
    times, positions, velocities = [], [], []
    for k, point in enumerate(msg.points):
        if len(point.positions) != len(names):
            raise FaultError(f"joint_trajectory.points[{k}].positions has {len(point.positions)} values "
                             f"for {len(names)} joint_names")
        times.append(stamp_to_ns(point.time_from_start) / NS_PER_S)
        positions.append(float(point.positions[index]))
        velocities.append(float(point.velocities[index]) if len(point.velocities) == len(names) else None)
    given = [v for v in velocities if v is not None]
    return stamp_to_ns(msg.header.stamp), times, positions, given if len(given) == len(velocities) else None


def subscribe_trajectory(node: SuiteNode, msg_type: type, topic: str, follower: TrajectoryFollower) -> RefusalCounter:
    """Hand every trajectory on ``topic`` to ``follower``; a bad one is refused and counted (the counter returned)."""
    refusals = RefusalCounter(node, topic)

    def receive(msg: Any) -> None:
        try:
            follower.take(*trajectory_points(msg, follower.axis))
        except CncError as err:
            refusals.refuse(str(err))

    node.create_subscription(msg_type, topic, node.guarded(receive), TRAJECTORY_QOS)
    return refusals
