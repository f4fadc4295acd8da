"""A streaming plan planned ahead of the tool in a process of its own (ROS-free).

A :class:`~cnc_contour_control.motion.plan_background.BackgroundPlanner` thread shares the interpreter lock with
the ticks of every node in its process. ``jerk_mode`` fir's chunks are planned, filtered and checked against P
(:mod:`~cnc_contour_control.motion.jerk_stream`), which costs several times what a (v, a) chunk does; on dense
CAM code at T = 1 ms that work and the ticks together need more than the one core the lock allows, and ticks
wait for the plan (``bench blending``, the composed graph). :class:`ProcessPlanner` moves the planning to a
child process (``python -m cnc_contour_control.motion.plan_process``, on another core):

1. a feeder thread starts the child and sends it the settings and the program, a batch of segments at a time
   (:mod:`~cnc_contour_control.motion.segment_codec`: encoded in bytecode that yields the lock, pickled as a
   few large buffers);
2. the child builds the same program and :class:`~cnc_contour_control.motion.plan_stream.StreamPlan` and says
   ready; until then the planner thread plans here, as a ``BackgroundPlanner`` does;
3. from then on the planner thread asks the child for chunk ``n`` (the next one not committed here) with the
   tool's profile time; the child plans up to it (the chunks this process planned meanwhile are planned there
   again, the same arithmetic on the same program), sends its segments, rows and phases, forgets behind the
   tool, and plans the following chunk while this process samples. The thread commits each answer
   (:meth:`StreamPlan.receive`), which checks that it follows what is committed.

A :class:`~cnc_contour_control.core.errors.CncError` in the child (a segment the limits refuse) comes back and is
raised where the thread's would be. A child that dies is a :class:`FaultError` naming it; a child that never
becomes ready leaves the planning here, and :meth:`ProcessPlanner.status_values` says why. The child ends when
asked, when its parent's end of the socket closes, or is killed at :meth:`ProcessPlanner.close` if it does not.
"""
from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import traceback
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import CncError, FaultError
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.plan_arrays import Phases
from cnc_contour_control.motion.plan_background import BackgroundPlanner
from cnc_contour_control.motion.plan_blocks import StreamSettings
from cnc_contour_control.motion.plan_stream import StreamPlan
from cnc_contour_control.motion.points import FloatArray
from cnc_contour_control.motion.segment_codec import decode_segments, encode_segments

#: Programmed segments per batch sent to the child.
BATCH_SEGMENTS = 2048
#: How long a child asked to end may take before it is killed, s.
CLOSE_WAIT_S = 5.0
#: The child's command line before its socket's descriptor.
CHILD_COMMAND: tuple[str, ...] = (sys.executable, "-m", __name__)


class _RecordingStream(StreamPlan):
    """The child's plan: every committed chunk kept as the message that hands it over."""

    def __init__(self, program: Program, settings: StreamSettings, chunk_segments: int) -> None:
        self.published: dict[int, dict[str, Any]] = {}
        self._chunks = 0
        super().__init__(program, settings, chunk_segments)

    def _publish(self, j: int, commit: int, speeds: FloatArray, last: bool, phases: Phases) -> None:
        segments, rows = self._blocks.export(j, j + commit)
        self.published[self._chunks] = {"j": j, "commit": commit, "speeds": speeds[:commit + 1].copy(), "last": last,
                                        "phases": phases, "segments": encode_segments(segments), "rows": rows,
                                        "start_s": self.planned_until_s}
        self._chunks += 1
        super()._publish(j, commit, speeds, last, phases)

    def chunk(self, index: int) -> dict[str, Any]:
        """Committed chunk ``index`` (planned as far as needed) with the plan's counters; older ones dropped."""
        while index not in self.published:
            if self.finished:
                raise FaultError(f"chunk {index} asked of a plan that ended at chunk {self._chunks - 1}")
            self.plan_chunk()
        message = self.published[index]
        for old in [k for k in self.published if k < index]:
            del self.published[old]
        message["counters"] = (self.replanned_chunks, self.over_tolerance_chunks, self.worst_deviation_m)
        message["total_m"] = self.total_length_m
        message["held_rows"] = self.held_rows()
        return message

    def prefetch(self, index: int) -> None:
        """Plan chunk ``index`` now if it is not (the parent samples meanwhile)."""
        if not self.finished and index not in self.published:
            self.plan_chunk()


def serve(conn: Connection) -> None:
    """The child's loop: build the plan from what the parent sends, then answer its requests for chunks."""
    settings, chunk_segments, meta, n_batches = conn.recv()
    segments: list[Any] = []
    for _ in range(n_batches):
        segments.extend(decode_segments(conn.recv()))
    program = Program(meta["name"], meta["axis_names"], tuple(segments), meta["dwells"], meta["path_tolerance_m"])
    stream = _RecordingStream(program, settings, chunk_segments)
    conn.send(("ready",))
    ahead: CncError | None = None  # met while planning ahead: the answer to the next request
    while True:
        try:
            request = conn.recv()
        except EOFError:
            return
        if request[0] == "close":
            return
        if ahead is not None:
            raise ahead
        _, index, tool_s = request
        stream.forget_before(tool_s)
        conn.send(("chunk", stream.chunk(index)))
        try:
            stream.prefetch(index + 1)
        except CncError as err:
            ahead = err


def _child_main(fd: int) -> None:
    conn = Connection(fd)
    try:
        serve(conn)
    except CncError as err:
        _send_quietly(conn, ("error", err))
    except Exception:  # any other failure goes to the parent, which names the process
        _send_quietly(conn, ("crash", traceback.format_exc()))
    finally:
        conn.close()


def _send_quietly(conn: Connection, message: tuple[Any, ...]) -> None:
    try:
        conn.send(message)
    except OSError:
        pass  # the parent is gone


class PlannerProcess:
    """The parent's handle on one planner child: started and fed by :meth:`start`, asked by :meth:`chunk`."""

    def __init__(self, stream: StreamPlan) -> None:
        self._stream = stream
        self.ready = threading.Event()
        self.failure = ""  # why the child never became ready, if it did not
        self._conn: Connection | None = None
        self._process: subprocess.Popen[bytes] | None = None
        self._closed = threading.Event()
        self._lock = threading.Lock()

    def start(self) -> None:
        """Start the child and send it the plan's settings and program (the feeder thread's work)."""
        try:
            self._launch()
            try:
                self._feed()
            except OSError as err:  # the child ended while it was sent the program (its answer may say why)
                self._receive()
                raise FaultError(f"the planner process (pid {self.pid}) ended{self._exit_note()} while it was sent "
                                 f"the program ({err})") from err
            reply = self._receive()
            if reply[0] != "ready":
                raise FaultError(f"the planner process answered {reply[0]!r} instead of ready")
            self.ready.set()
        except Exception as err:  # whatever stops the child: the planning stays here and says why
            self.failure = "closed before it was ready" if self._closed.is_set() else f"{type(err).__name__}: {err}"
            self._stop(0.0)

    def _launch(self) -> None:
        parent, child = socket.socketpair()
        package_root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, (package_root, os.environ.get("PYTHONPATH")))))
        self._conn = Connection(parent.detach())
        with child, self._lock:
            if self._closed.is_set():
                raise FaultError("closed while starting")
            self._process = subprocess.Popen([*CHILD_COMMAND, str(child.fileno())],
                                             pass_fds=[child.fileno()], env=env, stdin=subprocess.DEVNULL,
                                             stdout=subprocess.DEVNULL)

    def _feed(self) -> None:
        assert self._conn is not None
        stream, program = self._stream, self._stream.program
        segments = program.segments
        batches = range(0, len(segments), BATCH_SEGMENTS)
        meta = {"name": program.name, "axis_names": program.axis_names, "dwells": program.dwells,
                "path_tolerance_m": program.path_tolerance_m}
        self._conn.send((stream.settings, stream.chunk_segments, meta, len(batches)))
        for first in batches:
            if self._closed.is_set():
                raise FaultError("closed while sending the program")
            self._conn.send(encode_segments(list(segments[first:first + BATCH_SEGMENTS])))

    def _receive(self) -> tuple[Any, ...]:
        assert self._conn is not None
        try:
            reply: tuple[Any, ...] = self._conn.recv()
        except (EOFError, OSError) as err:
            raise FaultError(f"the planner process (pid {self.pid}) ended{self._exit_note()}: no answer") from err
        if reply[0] == "error":
            raise reply[1]
        if reply[0] == "crash":
            raise FaultError(f"the planner process (pid {self.pid}) failed:\n{reply[1]}")
        return reply

    def chunk(self, index: int, tool_s: float) -> dict[str, Any]:
        """Committed chunk ``index``, the tool at profile time ``tool_s`` (s) (once :attr:`ready`)."""
        assert self._conn is not None
        try:
            self._conn.send(("chunk", index, tool_s))
        except OSError as err:
            raise FaultError(f"the planner process (pid {self.pid}) ended{self._exit_note()}: cannot ask it "
                             f"for chunk {index}") from err
        message: dict[str, Any] = self._receive()[1]
        return message

    @property
    def pid(self) -> int | None:
        """The child's process id (None before it starts)."""
        return None if self._process is None else self._process.pid

    @property
    def exit_code(self) -> int | None:
        """The child's exit code once it has ended (None before)."""
        return None if self._process is None else self._process.poll()

    def _exit_note(self) -> str:
        code = None if self._process is None else self._process.poll()
        return "" if code is None else f" with exit code {code}"

    def close(self) -> None:
        """Ask the child to end and wait for it; kill it (it is ours) if it does not end in ``CLOSE_WAIT_S``."""
        with self._lock:
            self._closed.set()
        if self._conn is not None and self.ready.is_set():
            try:
                self._conn.send(("close",))
            except OSError:
                pass
        self._stop(CLOSE_WAIT_S if self.ready.is_set() else 0.0)
        if self._conn is not None:
            self._conn.close()

    def _stop(self, wait_s: float) -> None:
        """Wait ``wait_s`` for the child to end, then kill it (our own child, by its handle)."""
        process = self._process
        if process is None:
            return
        try:
            process.wait(timeout=wait_s)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


class ProcessPlanner(BackgroundPlanner):
    """A :class:`BackgroundPlanner` whose chunks a child process plans (once it is ready; here until then)."""

    def __init__(self, stream: StreamPlan, owner: object, lead_s: float | None = None) -> None:
        self.remote = PlannerProcess(stream)
        self._committed_chunks = 1  # the stream's constructor committed chunk 0 here
        #: Chunks the child planned and this process committed; the rows the child's plan held at the last one.
        self.received_chunks, self.child_held_rows = 0, 0
        super().__init__(stream, owner, lead_s)
        self._feeder = threading.Thread(target=self.remote.start, name="plan-feeder", daemon=True)
        self._feeder.start()

    def _step(self) -> None:
        if not self.remote.ready.is_set():  # the child is still starting (or never will): plan here
            super()._step()
        else:
            message = self.remote.chunk(self._committed_chunks, self._tool_s)
            if abs(message["start_s"] - self.stream.planned_until_s) > 1e-9:
                raise FaultError(f"the planner process's chunk {self._committed_chunks} starts at "
                                 f"{message['start_s']!r} s, the plan here ends at {self.stream.planned_until_s!r} s")
            segments = decode_segments(message["segments"])
            self.stream.receive(message["j"], message["commit"], message["speeds"], message["last"],
                                message["phases"], segments, message["rows"], message["total_m"])
            stream = self.stream
            stream.replanned_chunks, stream.over_tolerance_chunks, stream.worst_deviation_m = message["counters"]
            self.received_chunks += 1
            self.child_held_rows = int(message["held_rows"])
        self._committed_chunks += 1

    def _run(self) -> None:
        try:
            super()._run()
        finally:
            self.remote.close()

    def status_values(self) -> dict[str, str]:
        """The thread's status, where the chunks are planned (``plan_process``: a pid, or why not) and the rows the
        child's plan held at its last chunk."""
        values = super().status_values()
        remote = self.remote
        values["plan_process"] = (f"pid {remote.pid}" if remote.ready.is_set() else
                                  f"not used: {remote.failure}" if remote.failure else "starting")
        values["plan_process_held_rows"] = str(self.child_held_rows)
        return values


if __name__ == "__main__":
    _child_main(int(sys.argv[1]))
