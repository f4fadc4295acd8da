"""A joint trajectory as a goal's motion, with a trajectory controller's semantics (ROS-free).

FollowTrajectory (and control_msgs' FollowJointTrajectory) goals: a
trajectory names some of the machine's axes; the others hold where they
stand. Each named axis follows its points through
:class:`~cnc_contour_control.motion.trajectory_reference.JointTrajectoryReference`
(cubic Hermite with velocities, else linear), its times ``time_from_start``
counted from ``header.stamp`` (0: the goal's first tick; a later stamp: the axes
hold until then; an earlier one: from the first tick, as the reference must not
step; a trajectory over before the first tick is refused, OLD_HEADER_TIMESTAMP,
by the node). A first point after 0 starts from the hold position at rest, so
taking up a trajectory never steps the reference.

The trajectory's time τ advances at a rate ``r`` (1 while it runs): position
p(τ), velocity r·p'(τ), acceleration r²·p''(τ). A cancel ramps ``r`` linearly
to 0 over ``max_j |p'_j(τ)| / a_max_j`` (every axis decelerates within its
limit along the same path), so the axes stop *on the trajectory's path*, not
at once where the reference happens to be.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cnc_contour_control.core.errors import FaultError, ProgramError
from cnc_contour_control.core.lockstep import NS_PER_S
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import FloatArray
from cnc_contour_control.motion.reference_types import ReferenceSample
from cnc_contour_control.motion.trajectory_reference import JointTrajectoryReference


@dataclass(frozen=True)
class ControllerStateParams:
    """The interpolator's ``controller_state`` topic (reference, feedback, error, output per axis)."""

    controller_state_decimation: int = param(10, low=0, high=1_000_000, read_only=True,
                                             description="ticks per controller_state message (1: every tick, "
                                                         "0: none)")

    def __post_init__(self) -> None:
        check_ranges(self)


class TrajectoryGoalError(ProgramError):
    """A trajectory that cannot be followed; ``code`` is ``invalid_joints`` or ``invalid_goal``."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


@dataclass(frozen=True)
class TrajectoryPoints:
    """A JointTrajectory's content: joint names, ``time_from_start`` [s] (n,), positions [m] (n, n_joints),
    velocities [m/s] (n, n_joints) or None (every point without: linear)."""

    joint_names: tuple[str, ...]
    times_s: tuple[float, ...]
    positions_m: tuple[tuple[float, ...], ...]
    velocities_m_s: tuple[tuple[float, ...], ...] | None = None


class TrajectoryMotion:
    """A trajectory's reference tick by tick (see the module notes); duck-types the parts of
    :class:`~cnc_contour_control.motion.feed_override.LiveReference` a session uses (``request``, ``step``).

    Parameters
    ----------
    axes : sequence of str
        The machine's axes, in the reference's order.
    points : TrajectoryPoints
        The trajectory; every joint name must be an axis, each named once, with at least one point.
    hold_m : array
        Where the axes stand (the hold reference), m, shape ``(n_axes,)``.
    limits : AxisLimits
        The axes' limits: a point's velocity beyond ``max_velocity_m_s`` is refused; a cancel decelerates
        within ``max_acceleration_m_s2``.
    """

    def __init__(self, axes: Sequence[str], points: TrajectoryPoints, hold_m: FloatArray, limits: AxisLimits,
                 stamp_ns: int = 0) -> None:
        self.axes = tuple(axes)
        names = points.joint_names
        if not names:
            raise TrajectoryGoalError("invalid_joints", "the trajectory names no joint")
        for name in names:
            if name not in self.axes:
                raise TrajectoryGoalError("invalid_joints", f"joint {name!r} is not an axis of this machine; "
                                                            f"the axes are {list(self.axes)}")
        if len(set(names)) != len(names):
            raise TrajectoryGoalError("invalid_joints", f"a joint is named twice in {list(names)}")
        n = len(points.times_s)
        if n == 0:
            raise TrajectoryGoalError("invalid_goal", "the trajectory has no point")
        for i, row in enumerate(points.positions_m):
            if len(row) != len(names):
                raise TrajectoryGoalError("invalid_goal", f"point {i} has {len(row)} positions for "
                                                          f"{len(names)} joints")
        if points.velocities_m_s is not None and any(len(row) != len(names) for row in points.velocities_m_s):
            raise TrajectoryGoalError("invalid_goal", "every point's velocities must name every joint")
        self.hold_m = np.array(hold_m, dtype=float)
        self.indices = [self.axes.index(name) for name in names]
        self.max_acceleration_m_s2 = np.asarray(limits.max_acceleration_m_s2, dtype=float)
        times = list(points.times_s)
        self.joints: list[JointTrajectoryReference] = []
        for j, axis in enumerate(self.indices):
            positions = [row[j] for row in points.positions_m]
            velocities = None if points.velocities_m_s is None else [row[j] for row in points.velocities_m_s]
            t, p, v = times, positions, velocities
            if times[0] > 0.0:  # start from the hold at rest
                t, p = [0.0, *times], [float(self.hold_m[axis]), *positions]
                v = None if velocities is None else [0.0, *velocities]
            try:
                self.joints.append(JointTrajectoryReference(0, t, p, v))
            except FaultError as err:
                raise TrajectoryGoalError("invalid_goal", f"joint {names[j]}: {err}") from None
            limit = float(limits.max_velocity_m_s[axis])
            speeds = np.abs(np.diff(p)) / np.diff(t) if len(t) > 1 else np.zeros(0)
            if v is not None:
                speeds = np.concatenate([speeds, np.abs(v)])
            if speeds.size and float(np.max(speeds)) > limit * (1.0 + 1e-9):
                raise TrajectoryGoalError("invalid_goal", f"joint {names[j]}: speed {float(np.max(speeds)):.6g} m/s "
                                                          f"beyond its max_velocity_m_s {limit:g}")
        self.end_s = float(times[-1])
        self.starts_from_hold = times[0] > 0.0  # each joint's first point is then the hold (travel messages)
        self.stamp_ns = int(stamp_ns)
        self.tau_s = 0.0
        self.rate = 1.0
        self._last_ns: int | None = None
        self._stop_rate_per_s: float | None = None  # how fast the rate falls once stopping, 1/s

    @property
    def duration_s(self) -> float:
        """The trajectory's length at rate 1, s."""
        return self.end_s

    def begin(self, first_tick_ns: int) -> None:
        """The goal's first tick is at ``first_tick_ns``: a stamp after it delays the start (the axes hold)."""
        if self.stamp_ns > first_tick_ns:
            self.tau_s = -(self.stamp_ns - first_tick_ns) / NS_PER_S

    def request(self, relative_ns: int, requested_ratio: float) -> float:
        """The rate asked: 1 (a trajectory ignores the feed override); a cancel steps with 0."""
        return 1.0

    def _sample(self, tau_s: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        position, velocity, acceleration = self.hold_m.copy(), np.zeros(len(self.axes)), np.zeros(len(self.axes))
        stamp_ns = round(tau_s * NS_PER_S)
        for axis, joint in zip(self.indices, self.joints):
            position[axis], velocity[axis], acceleration[axis] = joint.sample(stamp_ns)
        return position, velocity, acceleration

    def step(self, relative_ns: int, ratio: float) -> ReferenceSample:
        """The reference ``relative_ns`` after the goal's first tick; ``ratio`` 0 decelerates to a stop on the path."""
        dt_s = 0.0 if self._last_ns is None else (relative_ns - self._last_ns) / NS_PER_S
        self._last_ns = relative_ns
        if ratio <= 0.0 and self._stop_rate_per_s is None:
            _, velocity, _ = self._sample(self.tau_s)
            stop_s = float(np.max(np.abs(velocity) / self.max_acceleration_m_s2))
            self._stop_rate_per_s = 1.0 / stop_s if stop_s > 0.0 else np.inf
        previous = self.rate
        if self._stop_rate_per_s is not None:
            self.rate = max(0.0, self.rate - self._stop_rate_per_s * dt_s)
        self.tau_s = min(self.end_s, self.tau_s + 0.5 * (previous + self.rate) * dt_s)
        position, velocity, acceleration = self._sample(self.tau_s)
        done = self.tau_s >= self.end_s
        rate = 0.0 if done else self.rate
        segment = max(0, int(np.searchsorted(self.joints[0].times_s, max(self.tau_s, 0.0), side="right")) - 1)
        return ReferenceSample(position_m=position, velocity_m_s=velocity * rate,
                               acceleration_m_s2=acceleration * rate * rate, path_length_m=0.0,
                               segment_index=segment, feed_m_s=float(np.linalg.norm(velocity * rate)),
                               programmed_feed_m_s=float(np.linalg.norm(velocity)), done=done,
                               profile_time_s=self.tau_s, feed_override_ratio=self.rate)
