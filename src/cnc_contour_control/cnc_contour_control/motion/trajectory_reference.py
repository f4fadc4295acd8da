"""One axis's reference from a joint trajectory (trajectory_msgs/JointTrajectory semantics; ROS-free).

A trajectory is points ``(t_i, p_i[, v_i])`` with ``t_i`` relative to its
start stamp (the message's ``header.stamp``; 0: the first tick that samples
it, as ros2_control's joint trajectory controller takes "now"). At a tick's
stamp ``t`` (s after the start) the reference is::

    t < t_0               the first point, at rest (but see below)
    t_i <= t <= t_i+1     cubic Hermite through (p_i, v_i), (p_i+1, v_i+1)   every point has a velocity
                          linear between p_i and p_i+1 (a = 0)               no point has one
    t >= t_last           the last point held: p_last, v = 0, a = 0

Position [m], velocity [m/s] and acceleration [m/s²] are the polynomial's
value and first two derivatives. A trajectory whose first point lies after
its start begins with the reference held when it was taken up (the previous
trajectory's sample, else the measured position) at ``t = 0``, velocity 0,
so taking up a trajectory never steps the reference. Before any trajectory
the reference holds the first measured position. A new trajectory replaces
the current one from its start on. A trajectory that cannot be followed is
refused and the current one kept: non-finite or unordered values, and once a
tick was sampled, a stale one (stamped, and over before that tick) or one from
the future (starting more than ``horizon_ns`` after it).

The per-tick evaluation is written out (a segment search and the Hermite
basis) because one sample per tick is all a servo needs;
``test_trajectory_reference`` checks it against ``scipy.interpolate``'s
``CubicHermiteSpline`` and linear ``make_interp_spline``.
"""
from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

from cnc_contour_control.core.config import require_choice, require_name
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.lockstep import NS_PER_S, stamp_horizon_ns
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.motion.travel import check_trajectory

__all__ = ["INTERPOLATIONS", "REFERENCE_SOURCES", "JointTrajectoryReference", "ReferenceSourceParams",
           "TrajectoryFollower"]

#: Where a servo's reference comes from: the suite's Reference topic, or a trajectory_msgs/JointTrajectory.
REFERENCE_SOURCES = ("reference", "joint_trajectory")
#: How a trajectory is interpolated between points: with velocities at every point, or without any.
INTERPOLATIONS = ("cubic_hermite", "linear")

#: One reference sample: position [m], velocity [m/s], acceleration [m/s²].
Sample = tuple[float, float, float]


@dataclass(frozen=True)
class ReferenceSourceParams:
    """The servo node's reference source (run parameters, read-only)."""

    reference_source: str = param("reference", read_only=True,
                                  description=f"where the reference comes from, one of {list(REFERENCE_SOURCES)}: "
                                              "the Reference topic (lockstep input) or a "
                                              "trajectory_msgs/JointTrajectory sampled at each tick's stamp")
    trajectory_topic: str = param("joint_trajectory", read_only=True,
                                  description="topic of the JointTrajectory (reference_source joint_trajectory)")
    travel_mm: tuple[float, ...] = param((), unit="mm", read_only=True,
                                         description="soft travel limits [min, max] of the axis: a trajectory "
                                                     "leaving them is refused (empty: none)")

    def __post_init__(self) -> None:
        require_choice("reference_source", self.reference_source, REFERENCE_SOURCES)
        require_name("trajectory_topic", self.trajectory_topic)
        travel = tuple(float(v) for v in self.travel_mm)
        if travel and not (len(travel) == 2 and all(map(math.isfinite, travel)) and travel[0] < travel[1]):
            raise ConfigError(f"travel_mm must be empty or [min, max], finite, min < max, got {list(travel)}")
        object.__setattr__(self, "travel_mm", travel)
        check_ranges(self)

    @property
    def travel(self) -> tuple[float, float] | None:
        """``(min_mm, max_mm)``, or None without travel limits."""
        return (self.travel_mm[0], self.travel_mm[1]) if self.travel_mm else None


def _finite(values: Sequence[float], name: str) -> list[float]:
    out = [float(v) for v in values]
    for i, value in enumerate(out):
        if not math.isfinite(value):
            raise FaultError(f"{name}[{i}] must be finite, got {value!r}")
    return out


class JointTrajectoryReference:
    """One joint's trajectory, sampled at absolute stamps (see the module docstring).

    Parameters
    ----------
    start_ns : int
        Stamp of ``t = 0`` [ns].
    times_s : sequence of float
        ``time_from_start`` of each point [s], shape (n,), >= 0 and strictly increasing, n >= 1.
    positions_m : sequence of float
        Position of each point [m], shape (n,).
    velocities_m_s : sequence of float or None
        Velocity of each point [m/s], shape (n,): cubic Hermite; None: linear.
    """

    def __init__(self, start_ns: int, times_s: Sequence[float], positions_m: Sequence[float],
                 velocities_m_s: Sequence[float] | None = None) -> None:
        self.start_ns = int(start_ns)
        self.times_s = _finite(times_s, "time_from_start")
        self.positions_m = _finite(positions_m, "positions")
        if not self.times_s or len(self.positions_m) != len(self.times_s):
            raise FaultError(f"a trajectory needs >= 1 point with one position each, got {len(self.times_s)} "
                             f"times and {len(self.positions_m)} positions")
        if self.times_s[0] < 0.0 or any(b <= a for a, b in zip(self.times_s, self.times_s[1:])):
            raise FaultError(f"time_from_start must be >= 0 and strictly increasing, got {self.times_s}")
        self.velocities_m_s = None if velocities_m_s is None else _finite(velocities_m_s, "velocities")
        if self.velocities_m_s is not None and len(self.velocities_m_s) != len(self.times_s):
            raise FaultError(f"velocities has {len(self.velocities_m_s)} values for {len(self.times_s)} points")

    @property
    def interpolation(self) -> str:
        """``cubic_hermite`` (velocities given) or ``linear``."""
        return INTERPOLATIONS[0] if self.velocities_m_s is not None else INTERPOLATIONS[1]

    def sample(self, stamp_ns: int) -> Sample:
        """Position [m], velocity [m/s], acceleration [m/s²] at ``stamp_ns``."""
        t_s = (int(stamp_ns) - self.start_ns) / NS_PER_S
        times, positions = self.times_s, self.positions_m
        if t_s >= times[-1]:
            return positions[-1], 0.0, 0.0
        if t_s < times[0]:
            return positions[0], 0.0, 0.0
        i = bisect_right(times, t_s) - 1
        h_s = times[i + 1] - times[i]
        s = (t_s - times[i]) / h_s
        p0, p1 = positions[i], positions[i + 1]
        if self.velocities_m_s is None:
            return p0 + (p1 - p0) * s, (p1 - p0) / h_s, 0.0
        return _hermite(s, h_s, p0, p1, self.velocities_m_s[i], self.velocities_m_s[i + 1])


def _hermite(s: float, h_s: float, p0: float, p1: float, v0: float, v1: float) -> Sample:
    """The cubic Hermite segment of length ``h_s`` [s] at ``s`` in [0, 1]: value and two time derivatives."""
    s2, s3 = s * s, s * s * s
    position = ((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * h_s * v0
                + (3 * s2 - 2 * s3) * p1 + (s3 - s2) * h_s * v1)
    velocity = ((6 * s2 - 6 * s) * (p0 - p1) / h_s + (3 * s2 - 4 * s + 1) * v0 + (3 * s2 - 2 * s) * v1)
    acceleration = ((12 * s - 6) * (p0 - p1) / (h_s * h_s) + ((6 * s - 4) * v0 + (6 * s - 2) * v1) / h_s)
    return position, velocity, acceleration


class TrajectoryFollower:
    """The reference of one axis from the latest trajectory it was given (see the module docstring).

    Parameters
    ----------
    axis : str
        The axis (the joint name it takes from a trajectory), named in refusals.
    horizon_ns : int
        How far after the latest sampled tick a trajectory's start may lie [ns] (default :func:`stamp_horizon_ns`).
    travel_mm : (float, float), optional
        Soft travel limits ``(min, max)`` [mm]: a trajectory whose interpolant leaves them is refused
        (:func:`~cnc_contour_control.motion.travel.check_trajectory`; from the reference held now when its
        first point lies later).
    """

    def __init__(self, axis: str, horizon_ns: int | None = None, travel_mm: tuple[float, float] | None = None) -> None:
        if not isinstance(axis, str) or not axis:
            raise ConfigError(f"axis must be a non-empty string, got {axis!r}")
        self.axis, self.travel_mm = axis, travel_mm
        self.horizon_ns = stamp_horizon_ns() if horizon_ns is None else int(horizon_ns)
        self.latest_ns: int | None = None  # the stamp of the latest sampled tick
        self.current: JointTrajectoryReference | None = None
        self._pending: tuple[int, list[float], list[float], list[float] | None] | None = None
        self._last: Sample | None = None
        self.received = 0
        self.taken = 0

    def take(self, start_ns: int, times_s: Sequence[float], positions_m: Sequence[float],
             velocities_m_s: Sequence[float] | None = None) -> None:
        """A new trajectory (start 0: the next sampled tick); checked now, used from the next :meth:`sample` on.

        Raises FaultError naming the reason for one that cannot be followed (the current one is kept).
        """
        checked = JointTrajectoryReference(start_ns, times_s, positions_m, velocities_m_s)
        self._check_window(checked)
        self._check_travel(checked)
        velocities = None if velocities_m_s is None else list(velocities_m_s)
        self._pending = (int(start_ns), list(times_s), list(positions_m), velocities)
        self.received += 1

    def _check_travel(self, trajectory: JointTrajectoryReference) -> None:
        """Refuse a trajectory leaving the travel limits (with the piece from the held reference, as taken up)."""
        if self.travel_mm is None:
            return
        times, positions, velocities = trajectory.times_s, trajectory.positions_m, trajectory.velocities_m_s
        held = times[0] > 0.0 and self._last is not None
        if held:
            assert self._last is not None, "held needs a held reference"
            times, positions = [0.0, *times], [self._last[0], *positions]
            velocities = None if velocities is None else [0.0, *velocities]
        check_trajectory(self.axis, self.travel_mm, times, positions, velocities, held)

    def _check_window(self, trajectory: JointTrajectoryReference) -> None:
        """Refuse a stamped trajectory over before the latest tick, or starting beyond the horizon after it."""
        if trajectory.start_ns == 0 or self.latest_ns is None:
            return
        end_ns = trajectory.start_ns + round(trajectory.times_s[-1] * NS_PER_S)
        now_s = self.latest_ns / NS_PER_S
        if end_ns < self.latest_ns:
            raise FaultError(f"stale trajectory: stamped {trajectory.start_ns / NS_PER_S:.6f} s, it ends at "
                             f"{end_ns / NS_PER_S:.6f} s, before the current tick at {now_s:.6f} s")
        if trajectory.start_ns > self.latest_ns + self.horizon_ns:
            raise FaultError(f"trajectory from the future: stamped {trajectory.start_ns / NS_PER_S:.6f} s, more than "
                             f"{self.horizon_ns / NS_PER_S:g} s after the current tick at {now_s:.6f} s")

    def sample(self, stamp_ns: int, position_m: float) -> Sample:
        """The reference at ``stamp_ns`` given the measured ``position_m`` [m] (held before any trajectory)."""
        self.latest_ns = int(stamp_ns)
        if self._pending is not None:
            self._take_up(stamp_ns, position_m)
        if self.current is None:
            if self._last is None:
                self._last = (float(position_m), 0.0, 0.0)
            return self._last
        self._last = self.current.sample(stamp_ns)
        return self._last

    def _take_up(self, stamp_ns: int, position_m: float) -> None:
        """Replace the current trajectory, starting from the reference held now when its first point lies later."""
        assert self._pending is not None
        start_ns, times, positions, velocities = self._pending
        self._pending = None
        start_ns = start_ns or int(stamp_ns)
        hold_m = self._last[0] if self._last is not None else float(position_m)
        if times[0] > 0.0:
            times, positions = [0.0, *times], [hold_m, *positions]
            velocities = None if velocities is None else [0.0, *velocities]
        self.current = JointTrajectoryReference(start_ns, times, positions, velocities)
        self.taken += 1
