"""A streaming plan planned ahead of the tool in a thread of its own (ROS-free).

On fine CAM code a tick cannot plan: one small step of
:meth:`~cnc_contour_control.motion.plan_stream.StreamPlan.plan_ahead` (64 planned segments, 64 programmed ones
blended) costs 5-17 ms of CPU, mostly per-call overheads of the blending and the limits (``bench blending``,
dense CAM), against a 1 ms tick. :class:`BackgroundPlanner` plans whole chunks (``MIN_CHUNK_SEGMENTS``, about
25 µs a segment) in a daemon thread whenever the committed phases end less than ``lead_s`` (profile time)
ahead of the tool, and forgets what is behind it (``StreamPlan.forget_before``). The plan's phase lists and
planned segments are changed only by that thread: appended (blending and limits, outside the lock), published
and forgotten under :attr:`BackgroundPlanner.condition`, which a tick holds while it samples. A tick that
reaches the end of the committed phases waits for the next chunk (:meth:`wait_until`: a late tick, counted
by the caller), never plans itself.

The thread's Python work holds the interpreter lock; at the default switch interval (5 ms) a tick waiting
for it would be late. Starting a planner lowers the process's switch interval to ``SWITCH_INTERVAL_S``
(never raises it) and puts it back once the last planner thread ends. The thread ends with the plan, when
the object that owns the stream is collected, or at
:meth:`close`; a :class:`~cnc_contour_control.core.errors.CncError` it meets (a segment the limits refuse) is
raised again by the next :meth:`wait_until`.
"""
from __future__ import annotations

import math
import sys
import threading
import weakref

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.motion.plan_stream import StreamPlan

#: The interpreter's switch interval while a planner runs, s: how long a tick may wait for the interpreter lock.
SWITCH_INTERVAL_S = 1.0e-4
#: How far the committed phases reach ahead of the tool (profile time, s) before the thread plans a chunk.
LEAD_S = 0.5
#: The same for ``jerk_mode`` fir: a chunk is published once the next one is planned and checked
#: (:mod:`~cnc_contour_control.motion.jerk_stream`), about 1 s of dense CAM at a time (0.5 s left the tool
#: waiting 120 times in 150 s at load 5, ``bench blending`` dense CAM).
FIR_LEAD_S = 2.0
_IDLE_WAIT_S = 0.5


class _SwitchInterval:
    """The process's switch interval at :data:`SWITCH_INTERVAL_S` while any planner thread runs, and back to what
    it was once the last one ends (a test process or a host making many plans keeps Python's 5 ms otherwise)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._running = 0
        self._before_s = sys.getswitchinterval()

    def lower(self) -> None:
        with self._lock:
            if self._running == 0:
                self._before_s = sys.getswitchinterval()
                sys.setswitchinterval(min(self._before_s, SWITCH_INTERVAL_S))
            self._running += 1

    def restore(self) -> None:
        with self._lock:
            self._running -= 1
            if self._running == 0:
                sys.setswitchinterval(self._before_s)


_switch_interval = _SwitchInterval()


class BackgroundPlanner:
    """Plans ``stream`` ahead of the tool in a daemon thread while ``owner`` lives.

    Parameters
    ----------
    stream : StreamPlan
        Attached at construction: its :meth:`StreamPlan.extend_to` then waits for this thread.
    owner : object
        The stream's user (a ``LiveReference``); the thread ends once it is collected.
    lead_s : float, optional
        Profile time (s) the committed phases should reach ahead of the tool (default :data:`LEAD_S`, with a
        jerk filter :data:`FIR_LEAD_S`).
    """

    def __init__(self, stream: StreamPlan, owner: object, lead_s: float | None = None) -> None:
        self.stream = stream
        self.lead_s = lead_s if lead_s is not None else LEAD_S if stream.settings.fir is None else FIR_LEAD_S
        self.condition = threading.Condition(threading.RLock())
        self._tool_s, self._wanted_s, self._closed = 0.0, 0.0, False
        self.error: CncError | None = None
        #: Calls of :meth:`wait_until` that had to wait for a chunk (a tick the planner made late).
        self.waits = 0
        self._owner = weakref.ref(owner)
        stream.guard, stream.background = self.condition, self
        _switch_interval.lower()
        self.thread = threading.Thread(target=self._run, name=f"plan-{stream.n_axes}-axes", daemon=True)
        self.thread.start()

    def tool_at(self, t_s: float) -> None:
        """The tool has reached profile time ``t_s`` (s): wake the thread if the plan's lead is short."""
        with self.condition:
            self._tool_s = t_s
            if self._needed():
                self.condition.notify_all()

    def wait_until(self, t_s: float) -> float:
        """Wait until the committed phases reach past ``t_s`` (s) or the end; the duration if known, else inf."""
        stream = self.stream
        with self.condition:
            self.waits += int(not stream.finished and stream.planned_until_s <= t_s)
            while not stream.finished and stream.planned_until_s <= t_s:
                if self.error is not None:
                    raise self.error
                self._wanted_s = max(self._wanted_s, t_s)
                self.condition.notify_all()
                self.condition.wait(_IDLE_WAIT_S)
            return stream.planned_until_s if stream.finished else math.inf

    def status_values(self) -> dict[str, str]:
        """The plan's state for a status: calls that waited for it, rows it holds, profile time planned ahead of the
        tool (s), whether it reached the program's end."""
        with self.condition:
            stream = self.stream
            return {"planner_waits": str(self.waits), "plan_held_rows": str(stream.held_rows()),
                    "plan_ahead_s": f"{max(stream.planned_until_s - self._tool_s, 0.0):.6f}",
                    "plan_finished": str(stream.finished).lower()}

    def close(self) -> None:
        """End the thread (after the chunk in hand); the stream plans no further."""
        with self.condition:
            self._closed = True
            self.condition.notify_all()

    def _needed(self) -> bool:
        stream = self.stream
        return not stream.finished and (stream.planned_until_s < self._tool_s + self.lead_s
                                         or stream.planned_until_s <= self._wanted_s)

    def _ended(self) -> bool:
        return self._closed or self.stream.finished or self._owner() is None

    def _run(self) -> None:
        try:
            self._plan()
        finally:
            _switch_interval.restore()

    def _step(self) -> None:
        """Commit the next chunk (outside the lock)."""
        self.stream.plan_chunk()

    def _plan(self) -> None:
        try:
            while True:
                with self.condition:
                    while not self._needed() and not self._ended():
                        self.condition.wait(_IDLE_WAIT_S)
                    if self._ended():
                        return
                    self.stream.forget_before(self._tool_s)
                self._step()
        except CncError as err:
            with self.condition:
                self.error = err
                self.condition.notify_all()
