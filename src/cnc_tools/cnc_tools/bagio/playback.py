"""Playback control of a replay: play, pause, speed and seek, between a viewer's thread and the replay's.

A replay's schedule (:class:`~cnc_tools.bagio.replay.ReplaySchedule`) hands out messages by *schedule time*,
``elapsed_s``: wall seconds since playback started at the replay's configured ``rate``. :class:`PlaybackClock`
makes that a function of wall time under the viewer's controls: playing, it advances ``speed / rate`` schedule
seconds per wall second (``speed``: log seconds per wall second, ``rate`` at first); paused, it stands; a seek
sets it. With the speed at the configured rate it is ``wall_s - start`` exactly, the replay without a viewer.

:class:`PlaybackControl` carries requests from any thread (the live server's) to the replay's executor, which
applies them between two publications and answers each with a :class:`PlaybackReport`. A request whose speed is
out of ``RATE_BOUNDS`` (or not finite) is refused whole, with the reason ``--rate`` would give.

Timeline: ``time_ns`` is the replay's log time as the viewer sees it, the playlist's start offset into the bag
(``ReplaySchedule.time_range_ns``) plus its log time since, with the empty stretches skipped. No rclpy, no clock.
"""
from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

from cnc_contour_control.core.config import require_range
from cnc_tools.bagio.replay import RATE_BOUNDS

PLAYING, PAUSED, ENDED = "playing", "paused", "ended"


@dataclass(frozen=True)
class PlaybackRequest:
    """A viewer's request.

    Attributes
    ----------
    playing
        Play (True) or pause (False).
    speed
        Log seconds per wall second, in ``RATE_BOUNDS``.
    seek_ns
        Timeline time to continue from, ns; None: no seek.
    request_id
        The viewer's id, echoed in the report.
    """

    playing: bool
    speed: float
    seek_ns: int | None = None
    request_id: str = ""


@dataclass(frozen=True)
class PlaybackReport:
    """The replay's state after a request, at its start or at its end.

    Attributes
    ----------
    status
        ``playing``, ``paused`` or ``ended``.
    time_ns
        Timeline time, ns.
    speed
        Log seconds per wall second.
    did_seek
        True when a seek was applied.
    request_id
        The request's id ("" when no request caused it).
    refused
        Why the request was refused (nothing changed); "" when applied.
    """

    status: str
    time_ns: int
    speed: float
    did_seek: bool = False
    request_id: str = ""
    refused: str = ""


class PlaybackClock:
    """Schedule time as a function of wall time under play, pause, speed and seek (module docstring).

    Parameters
    ----------
    rate
        The replay's configured rate (``ReplayConfig.rate``): schedule time runs at wall speed at this speed.
    """

    def __init__(self, rate: float) -> None:
        self.rate = require_range("rate", rate, *RATE_BOUNDS, "replay")
        self.speed = self.rate
        self.playing = True
        self._anchor_wall_s: float | None = None
        self._anchor_elapsed_s = 0.0

    @property
    def started(self) -> bool:
        """True once :meth:`start` was called."""
        return self._anchor_wall_s is not None

    def start(self, wall_s: float) -> None:
        """Playback starts (schedule time 0) at wall time ``wall_s``."""
        self._anchor_wall_s = wall_s

    def elapsed_s(self, wall_s: float) -> float:
        """Schedule time at wall time ``wall_s``, s (0 before the start)."""
        if self._anchor_wall_s is None or not self.playing:
            return self._anchor_elapsed_s
        return self._anchor_elapsed_s + (wall_s - self._anchor_wall_s) * (self.speed / self.rate)

    def wall_wait_s(self, schedule_wait_s: float) -> float | None:
        """Wall time until ``schedule_wait_s`` of schedule time has passed; None while paused."""
        return schedule_wait_s * self.rate / self.speed if self.playing else None

    def set(self, playing: bool, speed: float, wall_s: float) -> None:
        """Play or pause at ``speed`` from ``wall_s`` on; a speed out of ``RATE_BOUNDS`` is a ConfigError."""
        checked = require_range("rate", speed, *RATE_BOUNDS, "replay")
        self._rebase(self.elapsed_s(wall_s), wall_s)
        self.playing, self.speed = bool(playing), checked

    def seek(self, elapsed_s: float, wall_s: float) -> None:
        """Continue from schedule time ``elapsed_s`` at wall time ``wall_s``."""
        self._rebase(elapsed_s, wall_s)

    def _rebase(self, elapsed_s: float, wall_s: float) -> None:
        self._anchor_elapsed_s = elapsed_s
        if self._anchor_wall_s is not None:
            self._anchor_wall_s = wall_s


class PlaybackControl:
    """Requests in from any thread, reports out: the meeting point of a viewer and a replay (thread-safe).

    The viewer's side calls :meth:`ask` (a request, and the wait for its answer) and sets :attr:`report`, which
    gets every report no one waits for (the start, the end, an answer given after its asker gave up); the replay
    drains the requests with :meth:`take` on its own thread and answers each with :meth:`answer`.
    :attr:`time_ns` is the replay's timeline time at its last publication.

    Parameters
    ----------
    time_range_ns
        First and last timeline time of the playlist, ns (``ReplaySchedule.time_range_ns``).
    """

    def __init__(self, time_range_ns: tuple[int, int]) -> None:
        self.time_range_ns = time_range_ns
        self.time_ns = time_range_ns[0]
        self.report: Callable[[PlaybackReport], None] = _ignore
        self._changed = threading.Condition()
        self._requests: list[PlaybackRequest] = []
        self._waiting: dict[int, PlaybackReport | None] = {}

    def submit(self, request: PlaybackRequest) -> None:
        """Queue a request for the replay (its answer goes to :attr:`report`)."""
        with self._changed:
            self._requests.append(request)

    def ask(self, request: PlaybackRequest, timeout_s: float) -> PlaybackReport | None:
        """Queue a request and wait up to ``timeout_s`` for its answer (None: not answered in time, it will go to
        :attr:`report`)."""
        with self._changed:
            self._waiting[id(request)] = None
            self._requests.append(request)
            self._changed.wait_for(lambda: self._waiting[id(request)] is not None, timeout_s)
            return self._waiting.pop(id(request))

    def take(self) -> list[PlaybackRequest]:
        """The requests queued since the last call, oldest first."""
        with self._changed:
            taken, self._requests = self._requests, []
        return taken

    def answer(self, request: PlaybackRequest | None, report: PlaybackReport) -> None:
        """The replay's report (on ``request``, or None): to the asker if one waits, else to :attr:`report`."""
        with self._changed:
            waited = request is not None and id(request) in self._waiting
            if waited:
                self._waiting[id(request)] = report
                self._changed.notify_all()
        if not waited:
            self.report(report)


def _ignore(report: PlaybackReport) -> None:
    """No viewer to tell."""
