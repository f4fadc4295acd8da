"""The interpolator's FollowTrajectory action server (and control_msgs' FollowJointTrajectory where installed).

Only translation: a goal's ``trajectory_msgs/JointTrajectory`` becomes a
:class:`~cnc_contour_control.motion.trajectory_motion.TrajectoryMotion` run by the
interpolator's :class:`~cnc_contour_control.motion.program_session.ProgramSession`
(the same session as RunProgram: one goal at a time, hold in between, the same
tolerance checks, cancel, deactivation and machine stops). Joints not named hold;
``time_from_start`` counts from ``header.stamp`` (0 or past: the goal's first
tick; later: the axes hold until then; over before the latest tick:
OLD_HEADER_TIMESTAMP); path and goal tolerances and ``goal_time_tolerance`` as in
FollowJointTrajectory (0: the node's default, < 0: not checked). The result's
``error_code`` is FollowJointTrajectory's where it has one (SUCCESSFUL,
INVALID_GOAL, INVALID_JOINTS, PATH_TOLERANCE_VIOLATED, GOAL_TOLERANCE_VIOLATED),
ours after it (CANCELED, FAULTED, ABORTED, REJECTED), ``error_string`` always set.

``control_msgs`` is imported if present (a ROS install from apt has it; the
PyPI wheels do not): then the same callbacks also serve
``control_msgs/action/FollowJointTrajectory`` on ``follow_joint_trajectory``,
whose messages have the same fields, so MoveIt and other clients of a
joint_trajectory_controller drive the axes.
"""
from __future__ import annotations

from typing import Any

from action_msgs.msg import GoalStatus
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.task import Future
from trajectory_msgs.msg import JointTrajectoryPoint

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.goal_tolerances import GoalTolerances
from cnc_contour_control.motion.program_session import ProgramSession
from cnc_contour_control.motion.session_scores import ProgramOutcome
from cnc_contour_control.motion.trajectory_motion import TrajectoryGoalError, TrajectoryMotion, TrajectoryPoints
from cnc_contour_control.nodes.common import ns_to_stamp, stamp_to_ns
from cnc_contour_control.nodes.program_action import axis_tolerances
from cnc_contour_interfaces.action import FollowTrajectory

try:  # control_msgs: in a ROS install from apt, not in the PyPI wheels
    from control_msgs.action import FollowJointTrajectory  # type: ignore[import-not-found]  # absent from the wheels
except ImportError:  # served only as our FollowTrajectory
    FollowJointTrajectory = None

#: The actions' names, in the node's namespace.
ACTION_NAME = "follow_trajectory"
CONTROL_MSGS_ACTION_NAME = "follow_joint_trajectory"
#: The session's owner tag of these goals.
OWNER = "trajectory"
#: A session outcome -> the result's error_code (FollowTrajectory's constants, FollowJointTrajectory's numbers).
ERROR_CODES = {
    "completed": FollowTrajectory.Result.SUCCESSFUL,
    "path_tolerance_violated": FollowTrajectory.Result.PATH_TOLERANCE_VIOLATED,
    "goal_tolerance_violated": FollowTrajectory.Result.GOAL_TOLERANCE_VIOLATED,
    "canceled": FollowTrajectory.Result.CANCELED,
    "faulted": FollowTrajectory.Result.FAULTED,
    "aborted": FollowTrajectory.Result.ABORTED,
    "rejected": FollowTrajectory.Result.REJECTED,
    "invalid_goal": FollowTrajectory.Result.INVALID_GOAL,
    "invalid_joints": FollowTrajectory.Result.INVALID_JOINTS,
    "old_header_timestamp": FollowTrajectory.Result.OLD_HEADER_TIMESTAMP,
}


def duration_s(msg: Any) -> float:
    """A builtin_interfaces/Duration in seconds."""
    return float(msg.sec) + 1e-9 * float(msg.nanosec)


def points_from_msg(trajectory: Any) -> TrajectoryPoints:
    """A trajectory_msgs/JointTrajectory as the core's points (velocities only if every point gives them)."""
    points = list(trajectory.points)
    with_velocities = bool(points) and all(len(p.velocities) for p in points)
    return TrajectoryPoints(
        joint_names=tuple(str(n) for n in trajectory.joint_names),
        times_s=tuple(duration_s(p.time_from_start) for p in points),
        positions_m=tuple(tuple(float(v) for v in p.positions) for p in points),
        velocities_m_s=tuple(tuple(float(v) for v in p.velocities) for p in points) if with_velocities else None)


class TrajectoryActionServer:
    """FollowTrajectory (and FollowJointTrajectory if installed) on ``node``, run by ``session``.

    ``latest()`` gives the node's last tick: (stamp ns, reference sample, measured positions m) or None.
    """

    def __init__(self, node: Any, session: ProgramSession, limits: AxisLimits, feedback_period_s: float,
                 latest: Any) -> None:
        self.node, self.session, self.limits, self.latest = node, session, limits, latest
        self._handle: ServerGoalHandle | None = None
        self._outcome: Future | None = None
        self._joints: tuple[str, ...] = ()
        self._action_type: Any = FollowTrajectory
        self.servers = [self._server(FollowTrajectory, ACTION_NAME)]
        if FollowJointTrajectory is not None:
            self.servers.append(self._server(FollowJointTrajectory, CONTROL_MSGS_ACTION_NAME))
        node.create_timer(feedback_period_s, self._publish_feedback)

    def _server(self, action_type: Any, name: str) -> ActionServer:
        async def execute(goal_handle: ServerGoalHandle) -> Any:
            return await self._execute(goal_handle, action_type)
        return ActionServer(self.node, action_type, name, execute, cancel_callback=self._cancel)

    def _cancel(self, goal_handle: ServerGoalHandle) -> CancelResponse:
        if goal_handle is not self._handle or not self.session.cancel():
            return CancelResponse.REJECT
        self.node.get_logger().info("FollowTrajectory: cancel requested, decelerating on the path")
        return CancelResponse.ACCEPT

    def _start(self, request: Any) -> None:
        """Start the goal's trajectory at the next tick, or raise why not (TrajectoryGoalError: its code)."""
        if not self.node.armed:
            raise CncError("the interpolator is not active (lifecycle): activate it first")
        self.session.check_ready()
        try:
            tolerances = self.session.tolerances(GoalTolerances(
                path=axis_tolerances(request.path_tolerance), goal=axis_tolerances(request.goal_tolerance),
                goal_time_s=duration_s(request.goal_time_tolerance)))
        except CncError as err:
            raise TrajectoryGoalError("invalid_goal", str(err)) from None
        hold_m = self.session.hold_position_m
        assert hold_m is not None, "check_ready refuses an unknown position"
        points = points_from_msg(request.trajectory)
        stamp_ns = stamp_to_ns(request.trajectory.header.stamp)
        latest = self.latest()
        if stamp_ns and latest is not None and points.times_s and stamp_ns + points.times_s[-1] * 1e9 < latest[0]:
            raise TrajectoryGoalError("old_header_timestamp", f"the trajectory stamped {stamp_ns * 1e-9:.6f} s ends "
                                                              f"at {stamp_ns * 1e-9 + points.times_s[-1]:.6f} s, "
                                                              f"before the latest tick at {latest[0] * 1e-9:.6f} s")
        motion = TrajectoryMotion(self.session.axes, points, hold_m, self.limits, stamp_ns)
        self.session.start_motion(ACTION_NAME, motion, tolerances, OWNER)
        self._joints = tuple(request.trajectory.joint_names)
        self.node.get_logger().info(f"FollowTrajectory: joints {list(self._joints)}, "
                                    f"{len(request.trajectory.points)} points, {motion.duration_s:.3f} s")

    async def _execute(self, goal_handle: ServerGoalHandle, action_type: Any) -> Any:
        try:
            self._start(goal_handle.request)
        except TrajectoryGoalError as err:
            return self._end(goal_handle, action_type, err.code, str(err))
        except CncError as err:
            return self._end(goal_handle, action_type, "rejected", str(err))
        self._handle, self._outcome, self._action_type = goal_handle, Future(), action_type
        outcome: ProgramOutcome = await self._outcome
        if self._handle is goal_handle:
            self._handle = self._outcome = None
        return self._end(goal_handle, action_type, outcome.outcome, outcome.reason)

    def _end(self, goal_handle: ServerGoalHandle, action_type: Any, outcome: str, reason: str) -> Any:
        """The goal's terminal state (succeeded, canceled if asked, else aborted) and its result."""
        if outcome == "completed":
            goal_handle.succeed()
        elif outcome == "canceled" and goal_handle.status == GoalStatus.STATUS_CANCELING:
            goal_handle.canceled()
        else:
            goal_handle.abort()
        if outcome == "completed":  # one severity per call site (rclpy's logger refuses a change)
            self.node.get_logger().info(f"FollowTrajectory: {outcome}: {reason}")
        else:
            self.node.get_logger().warning(f"FollowTrajectory: {outcome}: {reason}")
        result = action_type.Result()
        result.error_code, result.error_string = int(ERROR_CODES[outcome]), reason
        return result

    def after_tick(self) -> None:
        """After each tick (and from the feedback timer): hand a trajectory goal's outcome to its client."""
        outcome = self.session.take_outcome(OWNER)
        if outcome is not None and self._outcome is not None and not self._outcome.done():
            self._outcome.set_result(outcome)

    def _publish_feedback(self) -> None:
        self.after_tick()
        latest = self.latest()
        handle = self._handle
        if handle is None or latest is None or not handle.is_active:
            return
        stamp_ns, sample, measured = latest
        index = [self.session.axes.index(name) for name in self._joints]
        desired = [float(sample.position_m[i]) for i in index]
        actual = [float(measured[i]) for i in index]
        msg = self._action_type.Feedback()
        msg.header.stamp = ns_to_stamp(stamp_ns)
        msg.joint_names = list(self._joints)
        msg.desired = JointTrajectoryPoint(positions=desired,
                                           velocities=[float(sample.velocity_m_s[i]) for i in index])
        msg.actual = JointTrajectoryPoint(positions=actual)
        msg.error = JointTrajectoryPoint(positions=[d - a for d, a in zip(desired, actual)])
        handle.publish_feedback(msg)

    def destroy(self) -> None:
        """Destroy the action servers (with the node)."""
        for server in self.servers:
            server.destroy()
