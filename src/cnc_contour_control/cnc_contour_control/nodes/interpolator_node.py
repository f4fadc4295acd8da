"""Interpolator node: part program -> per-axis reference every tick, and the latched path.

With ``feed_override_source`` other than ``none`` it follows the live feed
override (:class:`~cnc_contour_control.motion.feed_override.LiveReference`): the
requests come from ``feed_override.schedule_*`` or the ``feed_override`` topic
(:class:`~cnc_contour_control.motion.feed_override.OverrideInbox`), the applied ratio
is echoed in ``reference.feed_override_ratio``.

With ``program_source: action`` it reads no program at start-up: it runs
RunProgram goals one after another (:mod:`~cnc_contour_control.nodes.program_action`,
:class:`~cnc_contour_control.motion.program_session.ProgramSession`), answers every
tick in between with a hold reference, and republishes ``path`` for each program. In that
mode it also serves FollowTrajectory (:mod:`~cnc_contour_control.nodes.trajectory_action`:
a trajectory_msgs/JointTrajectory with a trajectory controller's semantics; control_msgs'
FollowJointTrajectory too where installed). Every ``controller_state_decimation`` ticks it
publishes ``~/controller_state``: reference, feedback, error per axis (the output, the servo's
command, is not seen here: NaN, ``output_known`` false).
"""
from __future__ import annotations

import math
from collections import deque
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.lockstep import StampMatcher, ns_to_s, stamp_horizon_ns
from cnc_contour_control.graph.stage_params import InterpolatorRunParams
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.feed_override import (
    LiveReference,
    OverrideConfig,
    OverrideInbox,
    check_source,
    message_ratio,
)
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.homing import HomingParams
from cnc_contour_control.motion.interpolation import Interpolator, with_planning_tolerance
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.program_file import read_program_file
from cnc_contour_control.motion.program_session import ProgramSession, ProgramSessionParams
from cnc_contour_control.motion.reference_types import ReferenceSample
from cnc_contour_control.motion.trajectory_motion import ControllerStateParams
from cnc_contour_control.motion.travel import TravelLimits
from cnc_contour_control.nodes import fast_cdr
from cnc_contour_control.nodes.common import (
    LATCHED_QOS,
    SuiteNode,
    spin_node,
    stamp_to_ns,
    wall_time_s,
)
from cnc_contour_control.nodes.conversions import joint_positions, program_to_path, reference_to_msg
from cnc_contour_control.nodes.homing_io import HomingService
from cnc_contour_control.nodes.parameters import declare_config
from cnc_contour_control.nodes.program_action import ProgramActionServer, stamped_cdr
from cnc_contour_control.nodes.refusals import RefusalCounter
from cnc_contour_control.nodes.trajectory_action import TrajectoryActionServer
from cnc_contour_interfaces.msg import ControllerState, FeedOverride, Path, Reference

#: Axis limits of a node started without them: 6000 mm/min and 1000 mm/s^2 on every axis.
DEFAULT_MAX_VELOCITY_M_S = 0.1
DEFAULT_MAX_ACCELERATION_M_S2 = 1.0

#: What controller_state says of its output (the interpolator does not see the servos' commands).
OUTPUT_SOURCE = "not known to the interpolator: each servo's command is on servo/<axis>/command"

#: The first tick's override may take this many feed_override_timeout_s: the regulator's publisher opens
#: only once its readers are discovered (a start-up cost, as the plant's startup_timeout_s allows for).
FIRST_OVERRIDE_TIMEOUT_FACTOR = 4.0
#: The status a streaming plan reports every ``PLAN_STATUS_PERIOD_S`` (wall s): ticks that waited for the planner,
#: rows it holds, its lead (:meth:`BackgroundPlanner.status_values`).
PLAN_STATUS = "streaming plan"
PLAN_STATUS_PERIOD_S = 1.0


class InterpolatorNode(SuiteNode):
    """Publishes ``reference`` for each ``joint_states`` tick and ``path`` once (latched)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("interpolator", **kwargs)

    def configure(self) -> None:
        """Lifecycle configure (nodes/lifecycle.py): the parameters validated, the program planned, the topics."""
        run = declare_config(self, InterpolatorRunParams)
        session_params = declare_config(self, ProgramSessionParams)
        state_params = declare_config(self, ControllerStateParams)
        self.travel = declare_config(self, TravelLimits, defaults={"travel_axes": list(run.axes)})
        self.homing = declare_config(self, HomingParams)
        if self.homing.require_homing and session_params.program_source == "file":
            raise ConfigError("require_homing needs program_source: action (the home service); a program_file "
                              "runs at start-up")
        self.axes, self.frame_id = run.axes, run.frame_id
        self.session: ProgramSession | None = None
        self.action: ProgramActionServer | None = None
        self.trajectory_action: TrajectoryActionServer | None = None
        self._latest: tuple[int, ReferenceSample, list[float]] | None = None  # last tick: stamp, reference, position
        self.home_service: HomingService | None = None
        if session_params.program_source == "file":
            self.interpolator = self._make_interpolator(run.program_file, run.feed_override_source)
            if self.travel.active:  # the planned path (blends included): refused before any axis moves
                self.travel.check_program(self.interpolator.program)
        else:
            self.session = self._make_session(run.feed_override_source, session_params)
            self.home_service = HomingService(self, self.session)
        self.reference_pub = self.gated_publisher(Reference, "reference", 1)
        self.path_pub = self.create_publisher(Path, "path", LATCHED_QOS)
        if self.session is None:  # the program as written: the scorer measures the blends' deviation as contour error
            self._publish_path(self.interpolator.programmed_program, self.interpolator, 0)
        else:
            self.action = ProgramActionServer(self, self.session, session_params.bag_path,
                                              session_params.feedback_period_s, self._path_cdr, self._publish_started)
            self.trajectory_action = TrajectoryActionServer(self, self.session, self.session.limits,
                                                            session_params.feedback_period_s, lambda: self._latest)
        self.state_decimation, self._state_ticks = state_params.controller_state_decimation, -1
        self.state_pub = (self.create_publisher(ControllerState, "~/controller_state", 10)
                          if self.state_decimation > 0 else None)
        # A joint state is answered at once (previous_tick: once feed_override(k-1) is in, watched by a timer);
        # the matcher checks stamps (from t = 0).
        self.matcher = StampMatcher(("joint_states",), math.inf, max_ahead_ns=stamp_horizon_ns())
        self.matcher.expect(0, wall_time_s())
        self.inbox = OverrideInbox(previous_tick=run.feed_override_source == "previous_tick",
                                   max_ratio=self.override_config.max_ratio)
        self.override_refusals = RefusalCounter(self, "feed_override")
        self._waiting: deque[JointState] = deque()
        self.subscribe_checked(JointState, "joint_states", self._accept, then=self._queue)
        self._blocked_since_s: float | None = None
        self._override_timeout_s = run.feed_override_timeout_s
        if run.feed_override_source in ("topic", "previous_tick"):
            self.subscribe_checked(FeedOverride, "feed_override", self._accept_override)
        if run.feed_override_source == "previous_tick":
            self.create_timer(min(0.1, run.feed_override_timeout_s / 4), self.guarded(self._watch_override))
        if self.live is not None and self.live.planner is not None:
            self.create_timer(PLAN_STATUS_PERIOD_S, self.guarded(self._report_plan))

    def deactivate(self) -> None:
        """Lifecycle deactivate: stop on the path within the limits (a running goal ends ABORTED once at rest; a
        live feed is held at 0 until activate); a fixed profile cannot stop on the path, so it refuses."""
        if self.session is not None:
            self.session.deactivate()
        elif self.live is None:
            raise ConfigError("a fixed feed profile cannot stop on the path: set feed_override_source "
                              "(topic, schedule, previous_tick) or program_source: action to deactivate mid-run")

    def _declare_planning(self, source: str) -> tuple[InterpolatorConfig, OverrideConfig, AxisLimits]:
        """The planner's options, the feed override's and the axis limits (config units: m/s, m/s^2)."""
        config = declare_config(self, InterpolatorConfig)
        override = declare_config(self, OverrideConfig, "feed_override")
        check_source(source, override)
        self.override_config = override
        n_axes = len(self.axes)
        limits = declare_config(self, AxisLimits, defaults={
            "max_velocity_m_s": [DEFAULT_MAX_VELOCITY_M_S] * n_axes,
            "max_acceleration_m_s2": [DEFAULT_MAX_ACCELERATION_M_S2] * n_axes})
        return config, override, limits

    def _make_session(self, source: str, params: ProgramSessionParams) -> ProgramSession:
        """Action mode: the session that runs goals (always through the live override: a cancel ramps to 0)."""
        config, override, limits = self._declare_planning(source)
        self.live: LiveReference | None = None
        return ProgramSession(self.axes, limits, config, override, params, self.travel, self.homing)

    def _make_interpolator(self, program_file: str, source: str) -> Interpolator:
        """The program's interpolator with the declared limits (config units: m/s, m/s^2) and options.

        With an on-line override the profile is planned for its ``max_ratio`` (``self.live``).
        """
        config, override, limits = self._declare_planning(source)
        program = read_program_file(program_file, self.axes)
        if tuple(program.axis_names) != self.axes:
            raise ConfigError(f"program axes {list(program.axis_names)} differ from parameter axes {list(self.axes)}")
        self.live = None if source == "none" else LiveReference(program, limits, config, override)
        return Interpolator(program, limits, config) if self.live is None else self.live.interpolator

    def _accept(self, msg: JointState) -> JointState | None:
        """A joint state's values, then its stamp, checked; None for a stale one."""
        joint_positions(msg, self.axes)
        added = self.matcher.add("joint_states", stamp_to_ns(msg.header.stamp), msg, wall_time_s())
        return None if added is None else msg

    def _accept_override(self, msg: FeedOverride) -> None:
        """A feed override's ratio (a bad one refused and counted, the last valid held); ticks it completes answered."""
        ratio = message_ratio(float(msg.requested_ratio), float(msg.applied_ratio), float(msg.quantum))
        refused = self.inbox.add(stamp_to_ns(msg.header.stamp), ratio)
        if refused is not None:
            self.override_refusals.refuse(refused)
        self._release()

    def _queue(self, msg: JointState) -> None:
        """Hold a tick until its override request is in (at once unless ``previous_tick``)."""
        self._waiting.append(msg)
        self._release()

    def _release(self) -> None:
        """Answer every held tick whose request is known, in order; note since when one waits."""
        while self._waiting and self.inbox.ready():
            self._blocked_since_s = None
            self.on_tick(self._waiting.popleft())
        if self._waiting and self._blocked_since_s is None:
            self._blocked_since_s = wall_time_s()

    def _watch_override(self) -> None:
        """Fault when a tick has waited longer than ``feed_override_timeout_s`` for the previous tick's override."""
        if self._blocked_since_s is None or self.finished:
            return
        waited_s = wall_time_s() - self._blocked_since_s
        first = self.inbox.awaited_ns == 0  # the regulator's first answer also waits for its readers' discovery
        limit_s = self._override_timeout_s * (FIRST_OVERRIDE_TIMEOUT_FACTOR if first else 1.0)
        if waited_s > limit_s:
            self.fault(f"no {self.resolve_topic_name('feed_override')} of the previous tick "
                       f"(stamp {self.inbox.awaited_ns} ns) within {limit_s} s (feed_override_timeout_s = "
                       f"{self._override_timeout_s} s"
                       f"{', x' + str(FIRST_OVERRIDE_TIMEOUT_FACTOR) + ' for the first' if first else ''})")

    def _report_plan(self) -> None:
        """A streaming plan's state on /diagnostics (see :data:`PLAN_STATUS`), until the node finishes."""
        planner = self.live.planner if self.live is not None else None
        if planner is not None and not self.finished:
            self.report(DiagnosticStatus.OK, PLAN_STATUS, planner.status_values())

    def _sample(self, stamp_ns: int) -> ReferenceSample:
        """The reference at the stamp: at the programmed feed, or following the override's request."""
        if self.live is None:
            return self.interpolator.reference(ns_to_s(stamp_ns))
        request = self.live.request(stamp_ns, self.inbox.take(stamp_ns))
        return self.live.step(stamp_ns, request if self.armed else 0.0)  # inactive: feed hold

    def on_tick(self, msg: JointState) -> None:
        """One tick: the reference at the joint state's stamp."""
        stamp_ns = stamp_to_ns(msg.header.stamp)
        positions, velocities = joint_positions(msg, self.axes)
        if self.session is None:
            sample = self._sample(stamp_ns)
        else:  # action mode: the running program's reference, or the hold
            sample = self.session.step(stamp_ns, positions, self.inbox.take(stamp_ns))
        self.reference_pub.publish(reference_to_msg(sample, self.axes, stamp_ns, self.frame_id))
        self._latest = (stamp_ns, sample, positions)
        if self.state_pub is not None:
            self._publish_state(msg, sample, positions, velocities)
        if self.action is not None:
            self.action.after_tick()
        if self.trajectory_action is not None:
            self.trajectory_action.after_tick()
        if self.home_service is not None:
            self.home_service.after_tick()

    def _publish_state(self, msg: JointState, sample: ReferenceSample, positions: list[float],
                       velocities: list[float]) -> None:
        """``~/controller_state`` every ``controller_state_decimation`` ticks: reference, feedback, error per axis."""
        self._state_ticks += 1
        if self._state_ticks % self.state_decimation:
            return
        assert self.state_pub is not None
        reference = [float(v) for v in sample.position_m]
        n = len(self.axes)
        owner = self.session.running_owner if self.session is not None else "program_file"
        self.state_pub.publish(ControllerState(
            header=msg.header, joint_names=list(self.axes), reference_position_m=reference,
            reference_velocity_m_s=[float(v) for v in sample.velocity_m_s], feedback_position_m=positions,
            feedback_velocity_m_s=velocities if len(msg.velocity) else [math.nan] * n,
            error_position_m=[r - p for r, p in zip(reference, positions)], output=[math.nan] * n,
            output_known=False, output_source=OUTPUT_SOURCE, goal=owner or ""))

    def _path_cdr(self, program: Program, live: LiveReference) -> bytes:
        """An action-mode program's ``path`` message, serialized (the planning thread calls this; stamp 0).

        By the suite's Python codec where there is one: rclpy's ``serialize_message`` is one C call that holds the
        interpreter lock throughout (1.3 s for 200 000 segments), stalling the tick's thread meanwhile.
        """
        msg = self._path_msg(program, live.interpolator, 0)
        codec = fast_cdr.codec_for(Path)
        return codec.encode(msg) if codec is not None else serialize_message(msg)

    def _publish_started(self, data: bytes, stamp_ns: int) -> None:
        """Each program of the action mode on the latched ``path``, stamped at its first tick."""
        self.path_pub.publish(stamped_cdr(data, stamp_ns))

    def _publish_path(self, program: Program, interpolator: Interpolator, stamp_ns: int) -> None:
        """``program`` as written on the latched ``path`` (see :meth:`_path_msg`)."""
        self.path_pub.publish(self._path_msg(program, interpolator, stamp_ns))

    def _path_msg(self, program: Program, interpolator: Interpolator, stamp_ns: int) -> Path:
        """``program`` as written, with the tolerance it is planned with (as the engine's), as a ``path`` message.

        Its ``planned_duration_s`` is NaN while a streaming plan (``look_ahead_segments`` below the program's
        length) has not reached the end: finishing it here would plan the whole program before the first tick.
        """
        duration_s = interpolator.planned_end_s(0.0)
        return program_to_path(with_planning_tolerance(program, interpolator.config), stamp_ns, self.frame_id,
                               duration_s if math.isfinite(duration_s) else math.nan)

    def fault(self, message: str) -> None:
        """Fault as every node does; a running goal ends as faulted with the reason."""
        if self.action is not None and not self.finished:
            self.action.abort(message)
            if self.trajectory_action is not None:
                self.trajectory_action.after_tick()
        super().fault(message)


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_contour_control interpolator``."""
    raise SystemExit(spin_node(InterpolatorNode, args))
