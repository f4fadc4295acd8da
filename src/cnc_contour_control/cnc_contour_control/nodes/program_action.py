"""The interpolator's RunProgram action server: goals to a :class:`ProgramSession`, its outcomes to results.

Only translation: the session (:mod:`cnc_contour_control.motion.program_session`)
decides. Every goal is accepted, so its client gets a result with a code and a
reason (ROS 2 gives a rejected goal no text; ros2_control's trajectory
controller accepts and aborts likewise): one that cannot run now (inactive,
busy, machine stopped) ends REJECTED at once, the reason logged and reported
WARN on ``/diagnostics``. An accepted goal is read and planned in a worker
thread, never on the tick's path (a 200 000-line file takes seconds), and its
``path`` message serialized there too (16 MB, over a second, for that file;
:func:`stamped_cdr` sets its stamp at the first tick): the axes hold
meanwhile, and a program that cannot be read or planned ends REJECTED with
the reason. Python's cyclic garbage collector stops every thread while it
scans the heap, 0.25 s for such a program's millions of objects and more in
a process of several nodes: it is off while the worker plans, and the plan's
objects are frozen out of its scans until the goal ends
(:func:`planning_heap`). The execute callback is a coroutine awaiting the outcome,
which the tick callback (or the feedback timer) resolves: it works on the
node's single-threaded executor (events or single).

The machine's state comes from ``/diagnostics``: the plant's and the servos'
latch reports of this namespace (:class:`~cnc_contour_control.axis.safety.MachineWatch`).
When the machine stops (an e-stop, a following-error trip) the running goal
ends FAULTED naming the first node that stopped and its cause, the reference
holds where the machine stands, and goals are rejected with the cause until
every node is reset and enabled.
"""
from __future__ import annotations

import gc
import math
import struct
import threading
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.task import Future

from cnc_contour_control.axis.safety import MachineWatch
from cnc_contour_control.core.errors import CncError
from cnc_contour_control.core.topics import RUN_ID_KEY
from cnc_contour_control.core.units import mm_to_m
from cnc_contour_control.motion.feed_override import LiveReference
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.goal_tolerances import AxisTolerance, GoalTolerances, Tolerances
from cnc_contour_control.motion.program_goal import ProgramGoal, SegmentSpec
from cnc_contour_control.motion.program_session import OUTCOMES, ProgramSession
from cnc_contour_control.motion.session_scores import ProgramFeedback, ProgramOutcome
from cnc_contour_interfaces.action import RunProgram

#: The action's name, in the node's namespace.
ACTION_NAME = "run_program"


def goal_from_msg(msg: Any) -> ProgramGoal:
    """A RunProgram goal message as the core's goal."""
    segments = tuple(SegmentSpec(int(s.kind), tuple(s.start_m), tuple(s.end_m), tuple(s.center_m),
                                 (int(s.plane_axes[0]), int(s.plane_axes[1])), float(s.feed_m_s))
                     for s in msg.segments)
    return ProgramGoal(gcode=msg.gcode, program_file=msg.program_file, segments=segments,
                       program_name=msg.program_name, feed_mm_min=float(msg.feed_mm_min),
                       path_tolerance_mm=float(msg.path_tolerance_mm))


def axis_tolerances(msgs: Any) -> tuple[AxisTolerance, ...]:
    """JointTolerance messages (ours or control_msgs', same fields; m, m/s) as the core's."""
    return tuple(AxisTolerance(str(t.name), float(t.position), float(t.velocity)) for t in msgs)


def tolerances_from_msg(msg: Any) -> GoalTolerances:
    """A RunProgram goal's tolerances (contour in mm, per axis in m; 0 the node's default, < 0 not checked)."""
    contour_mm = float(msg.contour_tolerance_mm)
    return GoalTolerances(contour_m=mm_to_m(contour_mm) if contour_mm > 0.0 else contour_mm,
                          path=axis_tolerances(msg.path_tolerance), goal=axis_tolerances(msg.goal_tolerance),
                          goal_time_s=float(msg.goal_time_s))


def feedback_to_msg(feedback: ProgramFeedback) -> Any:
    """The core's progress as a RunProgram feedback message."""
    msg = RunProgram.Feedback()
    for name in ("line_number", "segment_index"):
        setattr(msg, name, int(getattr(feedback, name)))
    for name in ("path_length_m", "total_length_m", "feed_m_s", "feed_override_ratio", "contour_error_m",
                 "following_error_m", "elapsed_s"):
        setattr(msg, name, float(getattr(feedback, name)))
    return msg


def stamped_cdr(data: bytes, stamp_ns: int) -> bytes:
    """A serialized message whose first field is a ``std_msgs/Header``, its stamp set to ``stamp_ns`` [ns].

    The CDR stream opens with a 4-byte encapsulation header (byte 1: 1 little, 0 big endian), then the
    stamp's ``int32 sec`` and ``uint32 nanosec``.
    """
    out = bytearray(data)
    struct.pack_into("<iI" if out[1] & 1 else ">iI", out, 4, *divmod(int(stamp_ns), 1_000_000_000))
    return bytes(out)


@contextmanager
def planning_heap() -> Iterator[None]:
    """No cyclic garbage collection while a plan is built; its objects frozen out of later scans (``gc.freeze``).

    Refcounting still frees them when the goal drops them; :meth:`ProgramActionServer._end` unfreezes.
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if enabled:
            gc.enable()


class PlanJob:
    """``work(*args)`` in a daemon thread (a stopping node does not wait for a plan); one job at a time runs.

    :meth:`done` and :meth:`result` are for the node's thread; the work's exception comes back from
    :meth:`result`. Jobs run one after another (a lock), so :func:`planning_heap` never nests.
    """

    _one_at_a_time = threading.Lock()

    def __init__(self, work: Callable[..., tuple[Program, LiveReference, bytes, Tolerances]], *args: Any) -> None:
        self._work, self._args = work, args
        self._result: tuple[Program, LiveReference, bytes, Tolerances] | None = None
        self._error: Exception | None = None
        self._done = threading.Event()
        threading.Thread(target=self._run, name="run_program_plan", daemon=True).start()

    def _run(self) -> None:
        try:
            with self._one_at_a_time:
                self._result = self._work(*self._args)
        except Exception as err:  # handed to the node's thread by result()
            self._error = err
        finally:
            self._done.set()

    def done(self) -> bool:
        """True once the work returned or raised."""
        return self._done.is_set()

    def result(self) -> tuple[Program, LiveReference, bytes, Tolerances]:
        """The work's result; its exception raised here."""
        if self._error is not None:
            raise self._error
        assert self._result is not None, "result() after done()"
        return self._result


def goal_name(msg: Any) -> str:
    """The name a goal's result carries before its program is read (its ``program_name``, else its source)."""
    if msg.program_name:
        return str(msg.program_name)
    if msg.program_file:
        return str(msg.program_file).rstrip("/").rsplit("/", 1)[-1].rsplit(".", 1)[0] or "program_file"
    return "segments" if len(msg.segments) else "gcode"


def outcome_to_result(outcome: ProgramOutcome, bag_path: str) -> Any:
    """The core's outcome as a RunProgram result message (``outcome`` by :data:`OUTCOMES` order)."""
    msg = RunProgram.Result()
    msg.outcome = OUTCOMES.index(outcome.outcome)
    msg.reason, msg.program_name, msg.bag_path = outcome.reason, outcome.program_name, bag_path
    for name in ("max_contour_error_m", "rms_contour_error_m", "max_following_error_m", "cycle_time_s",
                 "path_length_m", "total_length_m"):
        setattr(msg, name, float(getattr(outcome, name)))
    msg.ticks = int(outcome.ticks)
    return msg


class ProgramActionServer:
    """RunProgram on ``node``: one goal at a time, run by ``session``.

    ``path_of(program, live)`` serializes a planned program's ``path`` message (in the worker thread);
    ``publish_path(data, stamp_ns)`` publishes it at the program's first tick.
    """

    def __init__(self, node: Any, session: ProgramSession, bag_path: str, feedback_period_s: float,
                 path_of: Callable[[Program, LiveReference], bytes],
                 publish_path: Callable[[bytes, int], None]) -> None:
        self.node, self.session, self.bag_path = node, session, bag_path
        self.path_of, self.publish_path = path_of, publish_path
        self._handle: ServerGoalHandle | None = None
        self._outcome: Future | None = None
        self._planning: PlanJob | None = None
        self._path: tuple[Program, bytes] | None = None  # the started program's serialized path
        self.server = ActionServer(node, RunProgram, ACTION_NAME, self._execute, cancel_callback=self._cancel)
        node.create_timer(feedback_period_s, self._publish_feedback)
        self.machine = MachineWatch()
        node.create_subscription(DiagnosticArray, "/diagnostics", node.guarded(self._on_diagnostics), 100)

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        """The latch reports of this namespace's nodes: the machine stopped (the goal faults) or runs again."""
        namespace, own = self.node.get_namespace(), self.node.get_fully_qualified_name()
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if values.get(RUN_ID_KEY) == namespace and status.name != own:
                self.machine.observe(status.name, values)
        if self.machine.stopped and self.machine.cause != self.session.stop_cause:
            first = not self.session.stop_cause
            self.session.machine_stopped(self.machine.cause)
            self.after_tick()  # a running goal's outcome (faulted) to its client now
            if first:
                self.node.get_logger().warning(f"machine stopped: {self.machine.cause}")
        elif not self.machine.stopped and self.session.stop_cause:
            self.session.machine_running()
            self.node.get_logger().info("machine running again: goals are accepted")

    def _cancel(self, goal_handle: ServerGoalHandle) -> CancelResponse:
        """Accept a cancel of the running goal: the session stops it on the path."""
        if goal_handle is not self._handle or not self.session.cancel():
            return CancelResponse.REJECT
        self.node.get_logger().info("RunProgram: cancel requested, stopping on the path")
        return CancelResponse.ACCEPT

    async def _execute(self, goal_handle: ServerGoalHandle) -> Any:
        """Reserve the session and plan the goal in the worker thread (or refuse it); wait for its outcome."""
        name = goal_name(goal_handle.request)
        try:
            if not self.node.armed:
                raise CncError("the interpolator is not active (lifecycle): activate it first")
            hold_m = self.session.reserve(name)
        except CncError as err:
            return self._refused(goal_handle, name, str(err))
        self._handle, self._outcome = goal_handle, Future()
        self._planning = PlanJob(self._plan, goal_handle.request, hold_m)
        outcome: ProgramOutcome = await self._outcome
        if self._handle is goal_handle:
            self._handle = self._outcome = None
        if outcome.outcome == "rejected":
            self._report_refusal(outcome.program_name, outcome.reason)
        return self._end(goal_handle, outcome)

    def _refused(self, goal_handle: ServerGoalHandle, name: str, reason: str) -> Any:
        """A goal that cannot run now: aborted at once with REJECTED and the reason."""
        self._report_refusal(name, reason)
        outcome = ProgramOutcome("rejected", reason, name, math.nan, math.nan, math.nan, 0.0, 0.0, 0.0, 0)
        return self._end(goal_handle, outcome)

    def _report_refusal(self, name: str, reason: str) -> None:
        message = f"RunProgram goal {name!r} rejected: {reason}"
        self.node.get_logger().warning(message)
        self.node.report(DiagnosticStatus.WARN, message)

    def _end(self, goal_handle: ServerGoalHandle, outcome: ProgramOutcome) -> Any:
        """The goal's terminal state (succeeded, canceled if asked, else aborted) and its result."""
        if not self.session.busy and self._planning is None:
            gc.unfreeze()  # the ended plan's objects scanned (and their cycles collected) again
        if outcome.outcome == "completed":
            goal_handle.succeed()
        elif outcome.outcome == "canceled" and goal_handle.status == GoalStatus.STATUS_CANCELING:
            goal_handle.canceled()
        else:
            goal_handle.abort()
        self.node.get_logger().info(f"RunProgram: {outcome.program_name!r} {outcome.outcome}: {outcome.reason}")
        return outcome_to_result(outcome, self.bag_path)

    def _plan(self, request: Any, hold_m: Any) -> tuple[Program, LiveReference, bytes, Tolerances]:
        """In the worker thread: the goal message read and planned from the hold position ``hold_m`` [m], its
        serialized ``path`` and its tolerances."""
        with planning_heap():
            tolerances = self.session.tolerances(tolerances_from_msg(request))
            program, live = self.session.plan(goal_from_msg(request), hold_m)
            return program, live, self.path_of(program, live), tolerances

    def _collect_plan(self) -> None:
        """A plan the worker finished: start it at the next tick, or refuse the goal with the reason."""
        future = self._planning
        if future is None or not future.done():
            return
        self._planning = None
        if self.session.pending is None:  # the goal ended while it was planned (cancelled, machine stopped)
            if not self.session.busy:
                gc.unfreeze()
            return
        try:
            program, live, path, tolerances = future.result()
        except CncError as err:
            self.session.refuse(str(err))
        except Exception as err:  # a planner bug ends this goal with its reason, never the node
            self.node.get_logger().error("RunProgram: planning failed:\n" + traceback.format_exc())
            self.session.refuse(f"internal error while planning: {type(err).__name__}: {err}")
        else:
            self.session.start(program, live, tolerances)
            self._path = (program, path)
            planned_s = live.interpolator.planned_end_s(0.0)  # a streaming plan is not finished here (inf)
            self.node.get_logger().info(f"RunProgram: {program.name!r}, {len(program.segments)} segments, "
                                        + (f"{planned_s:.3f} s planned" if math.isfinite(planned_s) else "streamed"))

    def after_tick(self) -> None:
        """After each tick: take a finished plan, publish a program that started, hand over an outcome."""
        self._collect_plan()
        started = self.session.take_started()
        if started is not None and self._path is not None and self._path[0] is started[0]:
            self.publish_path(self._path[1], started[2])
            self._path = None
        outcome = self.session.take_outcome()
        if outcome is not None and self._outcome is not None and not self._outcome.done():
            self._outcome.set_result(outcome)

    def abort(self, reason: str) -> None:
        """The node faulted: end the running goal as faulted."""
        self.session.abort(reason)
        self.after_tick()

    def _publish_feedback(self) -> None:
        self.after_tick()  # a plan finished or an outcome while no tick comes
        feedback = self.session.feedback()
        if self._handle is not None and feedback is not None and self._handle.is_active:
            self._handle.publish_feedback(feedback_to_msg(feedback))

    def destroy(self) -> None:
        """Destroy the action server (with the node); a plan under way is dropped (its thread is a daemon)."""
        self._planning = None
        self.server.destroy()

