"""Progress of long commands on stderr: one status line on a terminal, plain lines elsewhere, nothing when quiet.

A command opens *tasks* (``with task("paper002 runs", total=12) as runs: ... runs.step()``); tasks nest
(a bench, inside it a sweep, inside that a generation's members) and the status line shows the open ones::

    bench paper002 › paper002 runs 5/12 · 41 s elapsed · ~57 s left

The elapsed time counts from the outermost task's start; the estimate is the outermost task with a total
and at least one step done, at its mean rate so far. Where the line goes depends on the stream:

- a terminal: the line is redrawn in place (``\\r``, cleared to its end, cut to the terminal's width) at
  each task's start and at steps, every :data:`REDRAW_S` at most; an inner task's end clears it, the
  outermost task's end leaves its last line with ``done``. When stdout is the same terminal, the command's
  own output clears the line and the line is drawn again below it, so a table printed mid-sweep does not
  run into it (output of child processes can);
- not a terminal (a pipe, a file, a CI log): plain lines, only when the outermost task starts or ends, when
  the outermost task with a total reaches another tenth of it, or at a step once :attr:`Reporter.interval_s`
  has passed since the last line; a dozen lines plus a few a minute at most, whatever the step rate;
- quiet (``cnc-contour --quiet``, :func:`set_quiet`), or a worker process of a pool: nothing.

Progress goes to stderr so stdout stays the command's parseable output. The process has one reporter
(:func:`reporter`); the CLI sets it quiet once, and the executors, the tuner and the benches open tasks on
it without passing it around. Time comes from a clock given to the reporter (``time.monotonic`` unless a
test gives another).
"""
from __future__ import annotations

import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Sized
from types import TracebackType
from typing import Any, Literal, TextIO, TypeVar, cast

from cnc_contour_control.core.errors import ConfigError

__all__ = ["Reporter", "Task", "format_duration", "reporter", "set_quiet", "task", "track"]

T = TypeVar("T")
#: How a reporter writes: ``auto`` (``terminal`` when the stream is a terminal, else ``lines``) or ``quiet``.
Mode = Literal["auto", "terminal", "lines", "quiet"]
#: Seconds between two plain lines when no tenth was reached meanwhile.
LINE_INTERVAL_S = 5.0
#: Least time between two redraws of a terminal's status line by steps [s] (a task's start always draws).
REDRAW_S = 0.1
#: Width of the status line when the terminal's cannot be read [characters].
FALLBACK_WIDTH = 100


def format_duration(seconds: float) -> str:
    """``42 s``, ``3 min 05 s`` or ``2 h 07 min`` (whole seconds, rounded)."""
    whole = max(0, round(seconds))
    if whole < 60:
        return f"{whole} s"
    if whole < 3600:
        return f"{whole // 60} min {whole % 60:02d} s"
    return f"{whole // 3600} h {whole % 3600 // 60:02d} min"


class Task:
    """One piece of long work on a :class:`Reporter`: a label, steps done and, when known, a total."""

    def __init__(self, owner: Reporter, label: str, total: int | None) -> None:
        if total is not None and (isinstance(total, bool) or not isinstance(total, int) or total < 0):
            raise ConfigError(f"total must be None or an integer >= 0, got {total!r}")
        self.owner, self.label, self.total = owner, label, total
        self.done = 0
        self.note = ""
        self.started_s = owner.clock()
        self.tenths_shown = 0

    def step(self, count: int = 1, note: str | None = None) -> None:
        """``count`` more steps done; ``note`` (when given) replaces the text shown after the count."""
        self.done += count
        if note is not None:
            self.note = note
        self.owner.changed(self)

    def text(self) -> str:
        """``label done/total (note)``: this task's part of the status line."""
        count = f" {self.done}/{self.total}" if self.total is not None else (f" {self.done}" if self.done else "")
        return f"{self.label}{count}" + (f" ({self.note})" if self.note else "")

    def remaining_s(self, now_s: float) -> float | None:
        """Seconds left at the mean step time so far; None without a total or a step."""
        if self.total is None or self.done <= 0:
            return None
        return (now_s - self.started_s) / self.done * max(0, self.total - self.done)

    def tenths(self) -> int:
        """Tenths of the total done (0 without a total)."""
        return 0 if not self.total else min(10, self.done * 10 // self.total)

    def close(self, *, stopped: bool = False) -> None:
        """End the task (idempotent); ``stopped``: by an exception (Ctrl-C, an error), not by finishing."""
        self.owner.closed(self, stopped=stopped)

    def __enter__(self) -> Task:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.close(stopped=kind is not None)


class Reporter:
    """Writes the open tasks' status to ``stream`` (None: ``sys.stderr`` at each write) as ``mode`` says.

    Parameters
    ----------
    stream : text stream or None
        Where to write; None looks ``sys.stderr`` up at each write (so a redirection made later holds).
    mode : {"auto", "terminal", "lines", "quiet"}
        ``auto``: ``terminal`` when the stream is a terminal, else ``lines``.
    clock : callable
        Seconds, monotonic (``time.monotonic``).
    interval_s : float
        Seconds between two plain lines when no task reached another tenth of its total.
    redraw_s : float
        Least seconds between two redraws of the terminal line by steps (>= 0).
    """

    def __init__(self, stream: TextIO | None = None, *, mode: Mode = "auto",
                 clock: Callable[[], float] = time.monotonic, interval_s: float = LINE_INTERVAL_S,
                 redraw_s: float = REDRAW_S) -> None:
        if mode not in ("auto", "terminal", "lines", "quiet"):
            raise ConfigError(f"mode must be one of auto, terminal, lines, quiet, got {mode!r}")
        if not interval_s > 0:
            raise ConfigError(f"interval_s must be > 0, got {interval_s!r}")
        if not redraw_s >= 0:
            raise ConfigError(f"redraw_s must be >= 0, got {redraw_s!r}")
        self._stream, self.mode, self.clock, self.interval_s = stream, mode, clock, interval_s
        self.redraw_s = redraw_s
        self._drawn_s = float("-inf")
        self._style: Literal["terminal", "lines", "quiet"] = "quiet"  # resolved when the outermost task opens
        self._stopped: list[Task] | None = None  # the open tasks when an exception ended the deepest of them
        self.tasks: list[Task] = []
        self._last_line_s = float("-inf")
        self._drawn = False  # a status line is on the terminal
        self._held = False  # the command's stdout has begun a line on the terminal: no drawing until it ends it

    @property
    def stream(self) -> TextIO:
        """The stream written to."""
        return self._stream if self._stream is not None else sys.stderr

    def style(self) -> Literal["terminal", "lines", "quiet"]:
        """How this reporter writes now (``auto`` resolved against the stream; quiet in a pool's worker)."""
        if self.mode == "quiet" or multiprocessing.parent_process() is not None:
            return "quiet"
        if self.mode == "auto":
            isatty = getattr(self.stream, "isatty", None)
            return "terminal" if callable(isatty) and isatty() else "lines"
        return self.mode

    def task(self, label: str, total: int | None = None) -> Task:
        """Open a task (use it in a ``with`` block); it nests inside the tasks open now."""
        opened = Task(self, label, total)
        self.tasks.append(opened)
        self._stopped = None
        if len(self.tasks) == 1:  # the style holds until the outermost task ends (one look at the stream)
            self._style = self.style()
            if self._style == "terminal":
                _guard_stdout(self)
        self._show(first=True)
        return opened

    def changed(self, changed: Task) -> None:
        """A task stepped: redraw, or write a line when the outermost task with a total reached another tenth
        of it, or when the interval says so."""
        self._stopped = None  # an exception that ended an inner task was handled: the work goes on
        if self._style != "quiet" and changed in self.tasks:
            leading = next((t for t in self.tasks if t.total is not None), None)
            self._show(tenth=changed is leading and changed.tenths() > changed.tenths_shown)

    def closed(self, task: Task, *, stopped: bool = False) -> None:
        """A task ended: the outermost's last line says ``done in`` (``stopped after`` when an exception ended
        it); an inner one's end clears the terminal's line."""
        if task not in self.tasks:
            return
        style = self._style
        outermost = self.tasks[0] is task
        if stopped and self._stopped is None:  # the deepest task an exception ended: the last line names it
            self._stopped = list(self.tasks)
        if outermost and style != "quiet":
            line = self.status(self.clock(), ending=True, stopped=stopped)
            if style == "terminal":
                self._write(("\n" if self._held else "") + f"\r{line[:max(10, self._width() - 1)]}\x1b[K\n")
                self._drawn = self._held = False
                _unguard_stdout(self)
            else:
                self._write(line + "\n")
        elif style == "terminal" and not stopped:
            self.before_output()
        self.tasks = self.tasks[:self.tasks.index(task)]
        if outermost:
            self._stopped = None

    def before_output(self) -> None:
        """The command writes to the terminal: clear the status line if one is drawn."""
        if self._drawn:
            self._write("\r\x1b[K")
            self._drawn = False

    def after_output(self, line_ended: bool) -> None:
        """The command wrote to the terminal: draw the status line again once its output ended a line."""
        self._held = not line_ended
        if line_ended and self.tasks and self._style == "terminal":
            self._show()

    def status(self, now_s: float, *, ending: bool = False, stopped: bool = False) -> str:
        """The status line of the open tasks at ``now_s`` (``ending``: the last one, ``stopped`` by an exception)."""
        if not self.tasks:
            return ""
        elapsed = format_duration(now_s - self.tasks[0].started_s)
        shown = self._stopped if stopped and self._stopped else self.tasks
        parts = [" › ".join(t.text() for t in shown),
                 (f"stopped after {elapsed}" if stopped else f"done in {elapsed}") if ending else f"{elapsed} elapsed"]
        left = next((r for r in (t.remaining_s(now_s) for t in self.tasks) if r is not None), None)
        if left is not None and not ending:
            parts.append(f"~{format_duration(left)} left")
        return " · ".join(parts)

    def _show(self, *, first: bool = False, tenth: bool = False) -> None:
        style = self._style
        if style == "quiet":
            return
        now_s = self.clock()
        if style == "terminal":
            if not self._held and (first or not self._drawn or now_s - self._drawn_s >= self.redraw_s):
                self._write(f"\r{self.status(now_s)[:max(10, self._width() - 1)]}\x1b[K")
                self._drawn, self._drawn_s = True, now_s
            return
        if (first and len(self.tasks) == 1) or tenth or now_s - self._last_line_s >= self.interval_s:
            for open_task in self.tasks:
                open_task.tenths_shown = open_task.tenths()
            self._last_line_s = now_s
            self._write(self.status(now_s) + "\n")

    def _width(self) -> int:
        """The columns of the stream's terminal (:data:`FALLBACK_WIDTH` when it does not say)."""
        try:
            columns = os.get_terminal_size(self.stream.fileno()).columns
        except (OSError, ValueError, AttributeError):
            return FALLBACK_WIDTH
        return columns or FALLBACK_WIDTH

    def _write(self, text: str) -> None:
        """Write and flush; a stream that fails (a closed pipe) silences the reporter, never the command."""
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            self._style = "quiet"


class _StdoutGuard:
    """``sys.stdout`` while a status line is drawn on the same terminal: the line is cleared before the
    command's own output and drawn again below it once that output ends a line (a table printed during a
    sweep does not run into the status line)."""

    def __init__(self, wrapped: TextIO, owner: Reporter) -> None:
        self.wrapped, self.owner = wrapped, owner

    def write(self, text: str) -> int:
        """Write ``text`` to the terminal around the status line."""
        self.owner.before_output()
        written = self.wrapped.write(text)
        if text:
            if text.endswith("\n"):
                self.wrapped.flush()
            self.owner.after_output(text.endswith("\n"))
        return written

    def __getattr__(self, name: str) -> Any:
        return getattr(self.wrapped, name)


def _same_terminal(one: TextIO, other: TextIO) -> bool:
    """Both streams are the same terminal device."""
    try:
        return one.isatty() and other.isatty() and os.ttyname(one.fileno()) == os.ttyname(other.fileno())
    except (OSError, ValueError, AttributeError):
        return False


def _guard_stdout(owner: Reporter) -> None:
    """Put a :class:`_StdoutGuard` on ``sys.stdout`` when it is the terminal the status line is drawn on."""
    if not isinstance(sys.stdout, _StdoutGuard) and _same_terminal(sys.stdout, owner.stream):
        sys.stdout = cast(TextIO, _StdoutGuard(sys.stdout, owner))


def _unguard_stdout(owner: Reporter) -> None:
    """Take ``owner``'s guard off ``sys.stdout`` (flushing what the command wrote)."""
    guard = sys.stdout
    if isinstance(guard, _StdoutGuard) and guard.owner is owner:
        guard.wrapped.flush()
        sys.stdout = guard.wrapped


_REPORTER = Reporter()


def reporter() -> Reporter:
    """The process's reporter (stderr; quiet after ``set_quiet(True)``)."""
    return _REPORTER


def set_quiet(quiet: bool) -> None:
    """Silence (True) or restore (False: ``auto``) the process's reporter (``cnc-contour --quiet``)."""
    _REPORTER.mode = "quiet" if quiet else "auto"


def task(label: str, total: int | None = None) -> Task:
    """Open a task on the process's reporter."""
    return _REPORTER.task(label, total)


def track(items: Iterable[T], label: str, total: int | None = None) -> Iterator[T]:
    """Yield ``items``, one step of a task ``label`` after each (total: ``len(items)`` when it has one)."""
    count = total if total is not None else (len(items) if isinstance(items, Sized) else None)
    with task(label, count) as opened:
        for item in items:
            yield item
            opened.step()
