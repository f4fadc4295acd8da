"""Playback control of ``replay --live``: the viewer's play, pause, seek and speed, through foxglove-sdk's
``PlaybackControl`` capability (with ``Time``: the server tells the viewer the replay's timeline time).

:class:`ReplayPlayback` is the server's listener: a ``PlaybackControlRequest`` becomes a
:class:`~cnc_tools.bagio.playback.PlaybackRequest` for the replay node, which applies it on its own thread; the
node's :class:`~cnc_tools.bagio.playback.PlaybackReport` goes back to every client as a ``PlaybackState`` carrying
the request's id, and a refusal (a speed out of the ``--rate`` bounds) also as a warning status naming the bound
and the value. The timeline is the replay's log time (``ReplaySchedule.time_range_ns``), and the live node stamps
each message it forwards with the timeline time of the replay's last publication (:meth:`log_time_ns`), so the
viewer's time axis, its seek bar and the messages agree.
"""
from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

from foxglove.websocket import (
    Capability,
    PlaybackCommand,
    PlaybackControlRequest,
    PlaybackState,
    PlaybackStatus,
    ServerListener,
    StatusLevel,
)

from cnc_tools.bagio.playback import ENDED, PAUSED, PlaybackControl, PlaybackReport, PlaybackRequest

if TYPE_CHECKING:
    from cnc_tools.live.server import LiveServer

#: Wall time between two ``Time`` messages at most, ns (the viewer's clock follows at 50 Hz).
TIME_PERIOD_NS = 20_000_000
#: Wall time a request waits for the replay's answer, s (it polls every ``CONTROL_PERIOD_S``, 20 ms).
ANSWER_TIMEOUT_S = 1.0
_STATUS = {ENDED: PlaybackStatus.Ended, PAUSED: PlaybackStatus.Paused}


class ReplayPlayback(ServerListener):
    """Listener of the live server of a replay: playback requests in, playback states out (module docstring)."""

    def __init__(self, control: PlaybackControl) -> None:
        self.control = control
        self.server: LiveServer | None = None
        self._time_sent_ns = 0
        control.report = self._on_report

    def server_options(self) -> dict[str, Any]:
        """The :class:`LiveServer` keywords: this listener, the capabilities and the playlist's time range."""
        return {"listener": self, "capabilities": [Capability.PlaybackControl, Capability.Time],
                "playback_time_range": self.control.time_range_ns}

    def attach(self, server: LiveServer) -> None:
        """The server started with :meth:`server_options` (reports before it are dropped)."""
        self.server = server

    def log_time_ns(self) -> int:
        """Log time of a forwarded message: the replay's timeline time; sends ``Time`` at most every 20 ms."""
        time_ns = self.control.time_ns
        wall_ns = time.monotonic_ns()
        if self.server is not None and wall_ns - self._time_sent_ns >= TIME_PERIOD_NS:
            self._time_sent_ns = wall_ns
            self.server.server.broadcast_time(time_ns)
        return time_ns

    def on_playback_control_request(self, playback_control_request: PlaybackControlRequest) -> PlaybackState | None:
        """A viewer's request (the server's thread): the replay applies it on its thread within
        ``CONTROL_PERIOD_S``; its state is the answer (None if the replay did not answer in time: it is sent when
        it does)."""
        request = playback_control_request
        report = self.control.ask(PlaybackRequest(playing=request.playback_command == PlaybackCommand.Play,
                                                  speed=float(request.playback_speed), seek_ns=request.seek_time,
                                                  request_id=request.request_id), ANSWER_TIMEOUT_S)
        return None if report is None else self._state(report)

    def _on_report(self, report: PlaybackReport) -> None:
        """A state no request waits for (the start, the end, a late answer), to every client (the replay's thread)."""
        if self.server is not None:
            self.server.server.broadcast_playback_state(self._state(report))

    def _state(self, report: PlaybackReport) -> PlaybackState:
        """The protocol's state of a report; a refusal is also a warning status, the viewer's time follows."""
        if self.server is not None:
            if report.refused:
                self.server.server.publish_status(f"playback request refused: {report.refused}", StatusLevel.Warning)
            self.server.server.broadcast_time(report.time_ns)
        return PlaybackState(status=_STATUS.get(report.status, PlaybackStatus.Playing), current_time=report.time_ns,
                             playback_speed=report.speed, did_seek=report.did_seek,
                             request_id=report.request_id or None)
