"""Replay node: republishes a bag's topics, raw, at their recorded times (as ``ros2 bag play``).

Given a :class:`~cnc_tools.bagio.playback.PlaybackControl` (``replay --live``), a viewer pauses, plays, seeks
and sets the speed: a timer takes the requests every :data:`CONTROL_PERIOD_S` (the events executor has no guard
conditions to wake it from another thread) and applies them on the node's thread between two publications, each
answered with a report.
"""
from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus

from cnc_contour_control.core.errors import BagError, ConfigError, FaultError
from cnc_contour_control.nodes.common import (
    LATCHED_QOS,
    LOCKSTEP_QOS,
    SuiteNode,
    describe,
    message_class,
    spin_node,
    wall_time_s,
)
from cnc_tools.bagio.playback import (
    ENDED,
    PAUSED,
    PLAYING,
    PlaybackClock,
    PlaybackControl,
    PlaybackReport,
    PlaybackRequest,
)
from cnc_tools.bagio.replay import (
    RATE_BOUNDS,
    SECONDS_MAX,
    Recording,
    ReplayConfig,
    ReplaySchedule,
    load_recording,
    lost_count,
    replay_summary,
    topics_of,
)

#: Poll period while waiting for readers, s.
_WAIT_PERIOD_S = 0.01
#: Shortest timer period, ns (a zero period would spin).
_MIN_PERIOD_NS = 1_000
#: Wall seconds between two looks for a viewer's playback requests.
CONTROL_PERIOD_S = 0.02
#: Default of ``wait_timeout_s``: wall seconds playback waits for its readers before it is a fault.
WAIT_TIMEOUT_S = 30.0


class ReplayNode(SuiteNode):
    """One raw publisher per recorded topic; a timer publishes each message's bytes when it is due.

    ``recording`` (optional) is a bag already loaded, e.g. by ``cnc-contour replay``; else the
    ``bag`` parameter names the bag to load. ``control`` (optional): a viewer's playback requests.
    """

    def __init__(self, recording: Recording | None = None, control: PlaybackControl | None = None,
                 **kwargs: Any) -> None:
        super().__init__("replay", **kwargs)
        bag = self.declare("bag", "" if recording is None else str(recording.source),
                           describe("bag folder (or .mcap file) to replay", read_only=True))
        config = self._declare_config()
        self.min_subscribers = self.declare("min_subscribers", 0, describe(
            "readers each topic of wait_topics must have before playback starts", 0, 1000, True, True))
        wait_topics = topics_of(self.declare("wait_topics", [""], describe(
            "replayed topics whose readers playback waits for (empty: every replayed topic)", read_only=True)))
        self.wait_timeout_s = self.declare("wait_timeout_s", WAIT_TIMEOUT_S, describe(
            "wall time playback waits for the readers before it is a fault, s", 0.01, SECONDS_MAX, True))
        if recording is None and not bag:
            raise BagError("replay: parameter bag (the bag folder to replay) is required")
        self.recording = recording if recording is not None else load_recording(bag, config.topics)
        self.schedule = ReplaySchedule(self.recording, config)
        self.outputs = {topic: self._publisher(topic, type_name) for topic, type_name in self.recording.topics.items()}
        self.awaited = self._awaited(wait_topics)
        self.clock = PlaybackClock(config.rate)
        self.waiting_since_s = wall_time_s()
        self.get_logger().info(f"replaying {self.recording.describe()}: {self.schedule.describe()}")
        self._timer = self.create_timer(_WAIT_PERIOD_S, self.guarded(self._tick))
        self.control = control
        if control is not None:
            self.create_timer(CONTROL_PERIOD_S, self.guarded(self._apply_requests))
            self._apply_requests()  # those made before this node existed (replay --paused) act from the start

    def _declare_config(self) -> ReplayConfig:
        """Rate, start offset, loop and topics from the parameters, validated by the core."""
        return ReplayConfig(
            rate=self.declare("rate", 1.0, describe("playback speed relative to the recording", *RATE_BOUNDS, True)),
            start_offset_s=self.declare("start_offset_s", 0.0, describe(
                "start this many seconds into the bag, s", 0.0, SECONDS_MAX, True)),
            loop=self.declare("loop", False, describe("start over at the end, until stopped", read_only=True)),
            topics=topics_of(self.declare("topics", [""], describe("topics to replay (empty: all)", read_only=True))),
            skip_empty_s=self.declare("skip_empty_s", 10.0, describe(
                "skip stretches of log time longer than this with no message, s (0: never)", 0.0, SECONDS_MAX, True)))

    def _publisher(self, topic: str, type_name: str) -> Any:
        qos = LATCHED_QOS if topic in self.recording.latched_topics else LOCKSTEP_QOS
        return self.create_publisher(message_class(type_name, topic), topic, qos)

    def _tick(self) -> None:
        """Start once the readers are there, publish what is due, then sleep until the next message."""
        if not self.clock.started:
            if not self._readers_ready():
                return
            self._start()
        self._publish_due(wall_time_s())
        self._sleep()

    def _publish_due(self, now_s: float, drain: bool = False) -> None:
        """Publish the messages due by wall time ``now_s``: a batch, or with ``drain`` every one."""
        elapsed_s, passes = self.clock.elapsed_s(now_s), self.schedule.passes
        while batch := self.schedule.step(elapsed_s):
            for message in batch:
                self.outputs[message.topic].publish(message.data)
            if not drain:
                break
        if self.control is not None:
            self.control.time_ns = self.schedule.time_ns(elapsed_s)
            if self.schedule.passes != passes:  # a loop started over: the viewer's time goes back, as by a seek
                self.control.answer(None, self._report(did_seek=True))

    def _sleep(self) -> None:
        """Wake when the next message is due (never while paused); finish when none is left."""
        wait_s = self.schedule.wait_s(self.clock.elapsed_s(wall_time_s()))
        if wait_s is None:
            self._finish()
            return
        wall_wait_s = self.clock.wall_wait_s(wait_s)
        if wall_wait_s is None:
            self._timer.cancel()
            return
        self._timer.timer_period_ns = max(int(wall_wait_s * 1e9), _MIN_PERIOD_NS)
        self._timer.reset()

    def _apply_requests(self) -> None:
        """Apply the viewer's requests (on this node's thread) and answer each."""
        assert self.control is not None  # the timer exists only with a control
        requests, now_s = self.control.take(), wall_time_s()
        if requests and self.clock.started and self.clock.playing and not self.finished:
            self._publish_due(now_s, drain=True)  # what was due goes out first: the stream agrees with the answer
        for request in requests:
            self.control.answer(request, self._apply(request, now_s))
        if requests and self.clock.started and not self.finished:
            self._sleep()

    def _apply(self, request: PlaybackRequest, now_s: float) -> PlaybackReport:
        try:
            self.clock.set(request.playing, request.speed, now_s)
        except ConfigError as err:
            return self._report(request.request_id, refused=str(err))
        if request.seek_ns is not None:
            self.clock.seek(self.schedule.seek(request.seek_ns), now_s)
        return self._report(request.request_id, did_seek=request.seek_ns is not None)

    def _report(self, request_id: str = "", did_seek: bool = False, refused: str = "") -> PlaybackReport:
        status = ENDED if self.finished else PLAYING if self.clock.playing else PAUSED
        time_ns = self.schedule.time_ns(self.clock.elapsed_s(wall_time_s()))
        return PlaybackReport(status, time_ns, self.clock.speed, did_seek, request_id, refused)

    def _awaited(self, wait_topics: tuple[str, ...]) -> dict[str, Any]:
        """The publishers whose readers playback waits for: those of ``wait_topics``, else every one."""
        unknown = sorted(set(wait_topics) - set(self.outputs))
        if unknown:
            raise ConfigError(f"replay: wait_topics {unknown} are not replayed; replayed: {sorted(self.outputs)}")
        return {t: p for t, p in self.outputs.items() if not wait_topics or t in wait_topics}

    def _readers_ready(self) -> bool:
        """True once every awaited topic has ``min_subscribers`` readers; a fault naming them after
        ``wait_timeout_s``."""
        short = {t: n for t, p in self.awaited.items() if (n := p.get_subscription_count()) < self.min_subscribers}
        what = ", ".join(f"{t} ({n} of {self.min_subscribers})" for t, n in short.items())
        self.waiting_for("readers", f"readers of {what}" if short else None)
        if short and wall_time_s() - self.waiting_since_s > self.wait_timeout_s:
            raise FaultError(f"replay: no {self.min_subscribers} reader(s) within wait_timeout_s = "
                             f"{self.wait_timeout_s:g} s on {what}")
        return not short

    def _start(self) -> None:
        """Note the wall time playback starts at; warn on /diagnostics if the bag is damaged."""
        self.clock.start(wall_time_s())
        integrity = self.recording.integrity
        if not integrity.complete:
            self.report(DiagnosticStatus.WARN, f"replaying a damaged bag: {integrity.describe()}",
                        {"lost": lost_count(integrity)})
        if self.control is not None:
            self.control.answer(None, self._report())

    def _finish(self) -> None:
        ok, text, values = replay_summary(self.schedule, self.recording)
        self._timer.cancel()
        self.finished = True  # before the report: whoever sees the report sees a finished node
        if self.control is not None:
            self.control.answer(None, self._report())
        self.report(DiagnosticStatus.OK if ok else DiagnosticStatus.WARN, text, values)
        self.get_logger().info(text)


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_tools replay --ros-args -p bag:=bags/run1/bag -p rate:=2.0``."""
    raise SystemExit(spin_node(ReplayNode, args))
