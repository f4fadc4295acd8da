"""Programs one after another on a running machine: the interpolator's action mode (ROS-free).

A :class:`ProgramSession` answers every tick (lockstep stays intact, the plant
keeps ticking). Idle, its reference holds the commanded position (at first
the measured one) at rest. :meth:`ProgramSession.prepare` turns a goal into a
planned program (a :class:`~cnc_contour_control.motion.feed_override.LiveReference`,
so a malformed program or one beyond the axis limits is refused before it
starts); :meth:`ProgramSession.start` queues it and it starts at the next
tick, its times counted from that tick's stamp. A node plans off its tick's
path: :meth:`ProgramSession.reserve` takes the session for a goal (the axes
hold meanwhile), :meth:`ProgramSession.plan` runs in another thread (it reads
only the frozen configuration), then :meth:`ProgramSession.start` or
:meth:`ProgramSession.refuse` (outcome ``rejected`` with the reason). Each tick

    reference   LiveReference.step(t_k - t_start, request)
    following   max_j |reference_j - position_j|
    contour     Program.contour_distance(position)   (the program as written)

with ``request`` the feed override asked (0 once cancelled: the feed-hold
ramp stops the reference on the path within the acceleration limits). The
program ends when its reference is at rest, at the end (completed) or on the
path after a cancel (canceled), plus ``settle_time_s`` during which the
following error is still scored; then the session holds the last reference.

Every goal carries tolerances (:mod:`~cnc_contour_control.motion.goal_tolerances`): each tick
while the reference moves, an axis beyond its path tolerance, or the contour error beyond the contour
tolerance, stops the program on the path (the feed-hold ramp) and it ends ``path_tolerance_violated``;
once the reference ended it completes when every axis is within its goal tolerance of the end and
stopped, else ``goal_tolerance_violated`` after ``goal_time``. Each reason names the axis (or the
contour), the amount, the time and the G-code line. A trajectory
(:class:`~cnc_contour_control.motion.trajectory_motion.TrajectoryMotion`, FollowTrajectory) runs the
same way (:meth:`ProgramSession.start_motion`), without a contour.

When the machine stops under a program (an e-stop, a following-error trip:
:meth:`ProgramSession.machine_stopped`) the program ends at once as faulted
with the cause, and until :meth:`ProgramSession.machine_running` the hold
follows the measured position (LinuxCNC: while the machine is off the
commanded position tracks the feedback), so the reference stands where the
machine came to rest; a goal is refused with the cause meanwhile.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cnc_contour_control.core.config import require_choice
from cnc_contour_control.core.errors import ConfigError, FaultError, ProgramError
from cnc_contour_control.core.lockstep import NS_PER_S, ns_to_s
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.core.units import mm_to_m
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig
from cnc_contour_control.motion.geometry import PREFILTER_MIN_SEGMENTS, FloatArray, Program
from cnc_contour_control.motion.goal_tolerances import (
    GOAL_VIOLATED,
    PATH_VIOLATED,
    GoalTolerances,
    ToleranceDefaults,
    ToleranceMonitor,
    Tolerances,
    resolve_tolerances,
)
from cnc_contour_control.motion.homing import HomedState, HomingParams, homing_program
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.program_goal import ProgramGoal, goal_program
from cnc_contour_control.motion.reference_types import ReferenceSample
from cnc_contour_control.motion.session_scores import (
    CONTOUR_CHECK_BATCH,
    SCORE_BATCH,
    LiveScores,
    ProgramFeedback,
    ProgramOutcome,
)
from cnc_contour_control.motion.trajectory_motion import TrajectoryGoalError, TrajectoryMotion
from cnc_contour_control.motion.travel import TravelLimits, check_trajectory

#: Where the interpolator's program comes from: ``file`` the ``program_file`` parameter, run once at start-up;
#: ``action`` RunProgram goals, any number in a row, holding position in between.
PROGRAM_SOURCES = ("file", "action")
#: How a program ended (the RunProgram result's outcome, in its constants' order: 0 is "unknown", so a
#: default-constructed result never reads as success). ``rejected``: refused before it started, the reason
#: given; ``aborted``: stopped on the path because the interpolator was deactivated; the two violations of a
#: goal's tolerances last (goal_tolerances).
OUTCOMES = ("unknown", "completed", "canceled", "faulted", "rejected", "aborted", PATH_VIOLATED, GOAL_VIOLATED)
#: The reason of a completed program (every outcome carries one), before its in-position figures.
COMPLETED_REASON = "completed: the program's end reached, in position"
#: The reason of a program stopped by the interpolator's deactivation.
DEACTIVATED_REASON = "aborted: the interpolator was deactivated; stopped on the path"
#: A reference slower than this on every axis is at rest, m/s (an exponential accel_decel never reaches 0).
STOPPED_SPEED_M_S = 1.0e-7


@dataclass(frozen=True)
class ProgramSessionParams:
    """The interpolator's program source (one of :data:`PROGRAM_SOURCES`) and the options of its action mode.

    Each field's unit, range and meaning are in its ``param`` declaration (they become the ROS parameters'
    descriptors); ``goal_time_s`` past the reference's end, a goal not in position ends goal_tolerance_violated.
    """

    program_source: str = param("file", read_only=True,
                                description="file: program_file run once; action: RunProgram goals in a row")
    start_tolerance_mm: float = param(1.0e-3, unit="mm", low=0.0, high=1000.0, read_only=True,
                                      description="largest distance of a non-G-code goal's start from the machine")
    settle_time_s: float = param(0.05, unit="s", low=0.0, high=60.0, read_only=True,
                                 description="time scored after a goal's reference came to rest")
    in_position_tolerance_mm: float = param(0.01, unit="mm", low=1.0e-6, high=100.0, read_only=True,
                                            description="a completed goal has every axis within this of its end")
    goal_time_s: float = param(5.0, unit="s", low=0.0, high=3600.0, read_only=True,
                               description="time after the reference ended within which the axes must be in "
                                           "position; later the goal ends goal_tolerance_violated")
    in_position_velocity_mm_s: float = param(1.0, unit="mm/s", low=1.0e-6, high=1000.0, read_only=True,
                                             description="a completed goal has every axis slower than this")
    contour_tolerance_mm: float = param(0.0, unit="mm", low=0.0, high=1000.0, read_only=True,
                                        description="a goal's default contour tolerance (0: not checked)")
    joint_path_tolerance_mm: float = param(0.0, unit="mm", low=0.0, high=1000.0, read_only=True,
                                           description="a goal's default per-axis path tolerance (0: not checked)")
    feedback_period_s: float = param(0.2, unit="s", low=0.01, high=10.0, read_only=True,
                                     description="wall time between two RunProgram feedback messages")
    bag_path: str = param("", read_only=True, description="the run's recording, returned in every result "
                                                          "(empty: none)")

    def __post_init__(self) -> None:
        require_choice("program_source", self.program_source, PROGRAM_SOURCES)
        if not isinstance(self.bag_path, str):
            raise ConfigError(f"bag_path must be a path, got {self.bag_path!r}")
        check_ranges(self)

    def tolerance_defaults(self) -> ToleranceDefaults:
        """A goal's default tolerances, SI units."""
        return ToleranceDefaults.from_mm(self.contour_tolerance_mm, self.joint_path_tolerance_mm,
                                         self.in_position_tolerance_mm, self.in_position_velocity_mm_s,
                                         self.goal_time_s)


@dataclass
class _Run:
    """A planned program (or a trajectory: ``program`` None) and where it stands."""

    name: str
    program: Program | None
    live: LiveReference | TrajectoryMotion
    scores: LiveScores
    monitor: ToleranceMonitor
    owner: str
    total_length_m: float
    lines: tuple[int, ...]  # G-code line of each planned segment (0: none)
    previous: tuple[int, FloatArray] | None = None  # the last tick's stamp and measured position
    velocity_m_s: FloatArray | None = None  # measured, by difference
    start_ns: int | None = None
    stopping: bool = False
    rest_ns: int | None = None
    last: ReferenceSample | None = None
    last_ns: int = 0
    stop_outcome: tuple[str, str] = ("canceled", "cancelled: stopped on the path")
    homing: bool = False  # the homing program (motion/homing.py): completed, every axis is homed


class ProgramSession:
    """Runs programs one after another and holds position in between (see the module notes).

    Parameters
    ----------
    axes : sequence of str
        Axis order of positions and programs.
    limits : AxisLimits
        The machine's axis limits.
    interpolator_config : InterpolatorConfig
        The planner's options (a goal's ``path_tolerance_mm`` > 0 replaces its tolerance).
    override_config : OverrideConfig
        The live feed override's options (the ramp of a cancel uses them too).
    params : ProgramSessionParams
    travel : TravelLimits, optional
        Soft travel limits every planned program must stay within (default: none).
    homing : HomingParams, optional
        Home position, homing feeds and ``require_homing`` (default: home at 0, not required).
    """

    def __init__(self, axes: Sequence[str], limits: AxisLimits, interpolator_config: InterpolatorConfig,
                 override_config: OverrideConfig, params: ProgramSessionParams, travel: TravelLimits | None = None,
                 homing: HomingParams | None = None) -> None:
        self.axes = tuple(axes)
        self.travel, self.homing = travel or TravelLimits(), homing or HomingParams()
        self.travel.bounds_m(self.axes)
        self.homing.check(self.axes, self.travel)
        self.homed = HomedState(self.axes, self.homing.require_homing)
        self.limits, self.interpolator_config, self.override_config = limits, interpolator_config, override_config
        self.params = params
        self.hold_position_m: FloatArray | None = None
        self._run: _Run | None = None
        self._started: _Run | None = None
        self._outcome: ProgramOutcome | None = None
        self.pending: str | None = None  # the name of a goal being planned (reserve .. start or refuse)
        self._pending_owner = self._outcome_owner = "program"  # which server's goal is planned, which ended
        self.stop_cause = ""  # why the machine is stopped ("" while it runs)

    @property
    def busy(self) -> bool:
        """True from :meth:`reserve` or :meth:`start` until the program's outcome is known."""
        return self._run is not None or self.pending is not None

    def check_ready(self) -> None:
        """A ProgramError with the reason if a goal cannot start now (busy, position unknown, machine stopped)."""
        if self._run is not None:
            raise ProgramError(f"busy: program {self._run.name!r} is running; cancel it or wait for its end")
        if self.pending is not None:
            raise ProgramError(f"busy: program {self.pending!r} is being planned; cancel it or wait for its end")
        if self.hold_position_m is None:
            raise ProgramError("no joint_states yet: the machine's position is unknown")
        if self.stop_cause:
            raise ProgramError(f"the machine is stopped: {self.stop_cause}; reset and enable it first")

    def prepare(self, goal: ProgramGoal) -> tuple[Program, LiveReference]:
        """The goal's program and its planned reference; a ProgramError with the reason if it cannot run now."""
        self.check_ready()
        self.homed.check()
        assert self.hold_position_m is not None, "check_ready refuses an unknown position"
        return self.plan(goal, self.hold_position_m)

    def reserve(self, name: str, owner: str = "program") -> FloatArray:
        """Take the session for the goal ``name`` while it is planned elsewhere; the hold position to plan from, m.

        Raises the reason of :meth:`check_ready`. The axes hold until :meth:`start` or :meth:`refuse`.
        """
        self.check_ready()
        self.homed.check()
        assert self.hold_position_m is not None, "check_ready refuses an unknown position"
        self.pending, self._pending_owner = name, owner
        return self.hold_position_m.copy()

    def plan(self, goal: ProgramGoal, hold_m: FloatArray) -> tuple[Program, LiveReference]:
        """The goal's program from ``hold_m`` [m] and its planned reference (reads only frozen configuration)."""
        program = goal_program(goal, self.axes, hold_m, mm_to_m(self.params.start_tolerance_mm))
        if len(program.segments) >= PREFILTER_MIN_SEGMENTS:
            program.segment_boxes()  # built here, not at the first live score (a tick)
        config = self.interpolator_config
        if goal.path_tolerance_mm > 0.0:
            config = dataclasses.replace(config, path_tolerance_mm=goal.path_tolerance_mm)
        live = LiveReference(program, self.limits, config, self.override_config)
        if self.travel.active:  # the planned path, blends included (a streaming plan blends it whole here)
            self.travel.check_program(live.interpolator.program)
        return program, live

    def home(self) -> str:
        """Start the homing program (motion/homing.py) at the next tick; what it does, or a ProgramError why not.

        Every axis is homed once it completes in position (at once when the machine stands at home).
        """
        self.check_ready()
        assert self.hold_position_m is not None, "check_ready refuses an unknown position"
        program = homing_program(self.axes, self.hold_position_m, self.homing)
        if program is None:
            self.homed.mark_all()
            return "every axis is at its home position: homed"
        config = dataclasses.replace(self.interpolator_config, path_tolerance_mm=0.0)  # exact stops
        live = LiveReference(program, self.limits, config, self.override_config)
        self._run = dataclasses.replace(self._program_run(program, live, self.tolerances(), "program"), homing=True)
        home_mm = ", ".join(f"{a} {1e3 * float(p):g}" for a, p in zip(self.axes, self.homing.position_m(self.axes)))
        return f"homing started: {len(program.segments)} moves, one axis at a time, to {home_mm} mm"

    def tolerances(self, requested: GoalTolerances | None = None) -> Tolerances:
        """A goal's tolerances resolved with the node's defaults (None: the defaults); a ProgramError naming a bad
        one."""
        return resolve_tolerances(requested or GoalTolerances(), self.axes, self.params.tolerance_defaults())

    def start(self, program: Program, live: LiveReference, tolerances: Tolerances | None = None,
              owner: str = "program") -> None:
        """Queue a prepared program: it starts at the next tick (``tolerances`` None: the node's defaults)."""
        self._queue(self._program_run(program, live, tolerances if tolerances is not None else self.tolerances(),
                                      owner))

    def _program_run(self, program: Program, live: LiveReference, tolerances: Tolerances, owner: str) -> _Run:
        batch = CONTOUR_CHECK_BATCH if math.isfinite(tolerances.contour_m) else SCORE_BATCH
        planned = live.interpolator.program
        lines = tuple(int(getattr(segment, "source_line", None) or 0) for segment in planned.segments)
        return _Run(program.name, program, live, LiveScores(program, batch, tolerances.contour_m),
                    ToleranceMonitor(self.axes, tolerances), owner, planned.total_length_m, lines)

    def start_motion(self, name: str, motion: TrajectoryMotion, tolerances: Tolerances | None = None,
                     owner: str = "trajectory") -> None:
        """Queue a trajectory (no contour; checked against ``tolerances``): it starts at the next tick.

        Refused (ProgramError) until homed under ``require_homing``, and (TrajectoryGoalError ``invalid_goal``)
        when a joint's points or Hermite extremes leave its travel.
        """
        self.homed.check()
        self._check_motion_travel(motion)
        tolerances = tolerances if tolerances is not None else self.tolerances()
        self._queue(_Run(name, None, motion, LiveScores(None), ToleranceMonitor(self.axes, tolerances), owner,
                         0.0, ()))

    def _check_motion_travel(self, motion: TrajectoryMotion) -> None:
        for axis, joint in zip(motion.indices, motion.joints):
            name = self.axes[axis]
            if name in self.travel.travel_axes:
                try:
                    check_trajectory(name, self.travel.limit_mm(name), joint.times_s, joint.positions_m,
                                     joint.velocities_m_s, motion.starts_from_hold)
                except FaultError as err:
                    raise TrajectoryGoalError("invalid_goal", str(err)) from None

    def _queue(self, run: _Run) -> None:
        if self._run is not None:
            raise ProgramError(f"busy: program {self._run.name!r} is running")
        self.pending = None
        self._run = run

    def refuse(self, reason: str) -> None:
        """The reserved goal cannot run (``reason``): it ends as ``rejected``."""
        self._end_pending("rejected", reason)

    def cancel(self) -> bool:
        """Stop the running program on its path (the feed-hold ramp), or end a planned one; False if none."""
        return self.stop("canceled", "cancelled: stopped on the path", "cancelled before it started")

    def deactivate(self) -> bool:
        """The interpolator is deactivated: stop on the path as :meth:`cancel` does, the outcome ``aborted``."""
        return self.stop("aborted", DEACTIVATED_REASON,
                         "aborted: the interpolator was deactivated before the program started")

    def stop(self, outcome: str, reason: str, unstarted_reason: str) -> bool:
        """Stop on the path; once at rest the program ends as ``outcome`` with ``reason`` (a program not yet
        started ends at once, with ``unstarted_reason``). False if none runs."""
        if self.pending is not None:
            self._end_pending(outcome, unstarted_reason)
            return True
        if self._run is None:
            return False
        if not self._run.stopping:
            self._run.stopping, self._run.stop_outcome = True, (outcome, reason)
        return True

    def abort(self, reason: str) -> None:
        """End the running or planned program at once as ``faulted`` (the node faulted; the reference stops here)."""
        self._end_pending("faulted", reason)
        if self._run is not None:
            self._finish(self._run, "faulted", reason)

    def machine_stopped(self, cause: str) -> None:
        """The machine stopped (``cause``): a running program ends as faulted; the hold follows the machine."""
        self.stop_cause = cause or "the machine stopped"
        self._end_pending("faulted", f"machine stopped: {self.stop_cause}")
        if self._run is not None:
            self._finish(self._run, "faulted", f"machine stopped: {self.stop_cause}")

    def _end_pending(self, outcome: str, reason: str) -> None:
        """A reserved goal ends before its first tick: no scores (NaN), no ticks."""
        if self.pending is None:
            return
        self._outcome = ProgramOutcome(outcome, reason, self.pending, math.nan, math.nan, math.nan, 0.0, 0.0, 0.0, 0)
        self._outcome_owner = self._pending_owner
        self.pending = None

    def machine_running(self) -> None:
        """The machine runs again (reset and enabled): the hold stays where the machine stands; goals welcome."""
        self.stop_cause = ""

    def step(self, stamp_ns: int, position_m: Sequence[float], requested_ratio: float = 1.0) -> ReferenceSample:
        """The reference of the tick at ``stamp_ns`` [ns] given the measured ``position_m`` [m, (n_axes,)]."""
        measured = np.asarray(position_m, dtype=float)
        if self.hold_position_m is None or self.stop_cause:
            self.hold_position_m = measured.copy()
        if self.stop_cause and self._run is not None:  # started while the machine stopped: it cannot move
            self.machine_stopped(self.stop_cause)
        run = self._run
        if run is None:
            return self._hold_sample(self.hold_position_m)
        if run.start_ns is None:
            run.start_ns, self._started = stamp_ns, run
            if isinstance(run.live, TrajectoryMotion):
                run.live.begin(stamp_ns)
        relative_ns = stamp_ns - run.start_ns
        ratio = 0.0 if run.stopping else run.live.request(relative_ns, requested_ratio)
        sample = run.live.step(relative_ns, ratio)
        if run.previous is not None and stamp_ns > run.previous[0]:
            run.velocity_m_s = (measured - run.previous[1]) / ns_to_s(stamp_ns - run.previous[0])
        run.previous = (stamp_ns, measured)
        line = self._line(run, sample.segment_index)
        run.scores.add(measured, sample.position_m, (ns_to_s(relative_ns), line))
        run.last, run.last_ns = sample, stamp_ns
        self._check_path(run, sample, relative_ns, measured, line)
        self._check_end(run, sample, stamp_ns, measured)
        return sample

    @staticmethod
    def _line(run: _Run, segment_index: int) -> int:
        return run.lines[segment_index] if 0 <= segment_index < len(run.lines) else 0

    def _check_path(self, run: _Run, sample: ReferenceSample, relative_ns: int, measured: FloatArray,
                    line: int) -> None:
        """While the reference moves: an axis beyond its path tolerance, or the contour beyond the contour
        tolerance, stops the program on the path; it ends ``path_tolerance_violated`` once at rest."""
        if run.stopping or run.rest_ns is not None:
            return
        reason = run.monitor.path(ns_to_s(relative_ns), sample.position_m, measured, line)
        if reason is None and run.scores.beyond is not None:
            distance_m, (time_s, at_line) = run.scores.beyond
            reason = run.monitor.contour(time_s, distance_m, at_line)
        if reason is not None:
            run.stopping, run.stop_outcome = True, (PATH_VIOLATED, reason + "; stopped on the path")

    def _check_end(self, run: _Run, sample: ReferenceSample, stamp_ns: int, measured: FloatArray) -> None:
        """Note when the reference came to rest (at the end, or held after a cancel); after settling, a program
        that reached its end completes once every axis is in position, or faults once ``goal_time_s`` has passed."""
        at_rest = float(np.max(np.abs(sample.velocity_m_s))) <= STOPPED_SPEED_M_S
        held = run.stopping and sample.feed_override_ratio == 0.0
        if run.rest_ns is None and at_rest and (sample.done or held):
            run.rest_ns = stamp_ns
        if run.rest_ns is None:
            return
        waited_s = ns_to_s(stamp_ns - run.rest_ns)
        if waited_s < self.params.settle_time_s:
            return
        if not sample.done:
            self._finish(run, *run.stop_outcome)
            return
        end_m = np.asarray(sample.position_m, dtype=float)
        off_m = np.abs(measured - end_m)
        velocity_m_s = run.velocity_m_s if run.velocity_m_s is not None else np.zeros(len(self.axes))
        tolerances = run.monitor.tolerances
        if run.monitor.in_goal(end_m, measured, velocity_m_s):
            self._finish(run, "completed", f"{COMPLETED_REASON}: every axis within its goal tolerance (largest "
                                           f"{1e3 * float(np.max(tolerances.goal_m)):g} mm) of the end and "
                                           f"stopped (largest distance {1e6 * float(np.max(off_m)):.1f} µm) "
                                           f"{waited_s:.3f} s after the reference ended")
        elif waited_s >= tolerances.goal_time_s:
            assert run.start_ns is not None, "a run that ticked has a start"
            self._finish(run, GOAL_VIOLATED, run.monitor.goal(
                ns_to_s(stamp_ns - run.start_ns), waited_s, end_m, measured, velocity_m_s,
                self._line(run, sample.segment_index)))

    def _hold_sample(self, hold_m: FloatArray) -> ReferenceSample:
        zeros = np.zeros(len(self.axes))
        return ReferenceSample(position_m=hold_m.copy(), velocity_m_s=zeros,
                               acceleration_m_s2=zeros.copy(), path_length_m=0.0, segment_index=0, feed_m_s=0.0,
                               programmed_feed_m_s=0.0, done=True)

    def _finish(self, run: _Run, outcome: str, reason: str) -> None:
        scores = run.scores
        rms = scores.rms_contour_m
        ticked = scores.ticks > 0
        end_ns = run.rest_ns if run.rest_ns is not None else run.last_ns
        self._outcome_owner = run.owner
        self._outcome = ProgramOutcome(
            outcome=outcome, reason=reason, program_name=run.name,
            max_contour_error_m=scores.max_contour_m if ticked else math.nan, rms_contour_error_m=rms,
            max_following_error_m=scores.max_following_m if ticked else math.nan,
            cycle_time_s=ns_to_s(end_ns - run.start_ns) if run.start_ns is not None else 0.0,
            path_length_m=run.last.path_length_m if run.last is not None else 0.0,
            total_length_m=run.total_length_m, ticks=scores.ticks)
        if run.last is not None:
            self.hold_position_m = np.array(run.last.position_m, dtype=float)
        if run.homing and outcome == "completed":
            self.homed.mark_all()
        self._run = None

    def take_started(self) -> tuple[Program, LiveReference, int] | None:
        """Once per program: (program, planned reference, start stamp ns) after its first tick; else None (and for a
        trajectory)."""
        run, self._started = self._started, None
        if run is None or run.start_ns is None or run.program is None or not isinstance(run.live, LiveReference):
            return None
        return run.program, run.live, run.start_ns

    def take_outcome(self, owner: str = "program") -> ProgramOutcome | None:
        """Once per goal: its outcome after it ended, to the server ``owner`` that started it; else None."""
        if self._outcome is None or self._outcome_owner != owner:
            return None
        outcome, self._outcome = self._outcome, None
        return outcome

    @property
    def running_owner(self) -> str | None:
        """The server whose goal runs or is planned (None: holding)."""
        if self._run is not None:
            return self._run.owner
        return self._pending_owner if self.pending is not None else None

    def feedback(self) -> ProgramFeedback | None:
        """The running program's progress (None before its first tick or when idle)."""
        run = self._run
        if run is None or run.last is None or run.start_ns is None:
            return None
        run.scores.flush()
        sample = run.last
        return ProgramFeedback(
            line_number=self._line(run, sample.segment_index), segment_index=int(sample.segment_index),
            path_length_m=float(sample.path_length_m), total_length_m=float(run.total_length_m),
            feed_m_s=float(sample.feed_m_s), feed_override_ratio=float(sample.feed_override_ratio),
            contour_error_m=run.scores.latest_contour_m, following_error_m=run.scores.latest_following_m,
            elapsed_s=(run.last_ns - run.start_ns) / NS_PER_S)
