"""Replay core: a bag's raw messages in log-time order and the schedule that maps log time to wall time.

``cnc-contour replay`` and the ``replay`` node republish a recorded run as
``ros2 bag play`` would. This module decides *what* is published *when*; the
node only reads its clock and publishes the bytes. No rclpy, no message types.

Reading reuses :func:`cnc_tools.bagio.raw_bag.read_raw`: the index when the file is
intact, else the salvage scan, whose readable prefix is replayed and whose loss
the recording's ``integrity`` states.

Timing (``ros2 bag play`` semantics): with ``t0`` the first log time plus
``start_offset_s``, a message logged at ``t`` is due ``(t - t0) / rate`` seconds
after playback starts. Messages logged before ``t0`` are skipped, except the
last one of each latched topic (the program's path), which is due at once so a
replay from the middle still carries the geometry. A stretch of log time with no
message longer than ``skip_empty_s`` is skipped (the next message is due at
once), as ``rosbag play --skip-empty`` did: the suite's bags stamp lockstep
topics in simulation time from 0 but ``/diagnostics`` in system time, decades
later. With ``loop`` the playlist starts over when it ends, pass ``p`` shifted
by ``p`` times its duration.
"""
from __future__ import annotations

from bisect import bisect_left
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from cnc_contour_control.core.config import require_range
from cnc_contour_control.core.errors import BagError, ConfigError
from cnc_contour_control.core.lockstep import NS_PER_S
from cnc_tools.bagio.bag import PATH_TYPE
from cnc_tools.bagio.raw_bag import locate, read_raw
from cnc_tools.run_record import BagIntegrity

#: Bounds of ``rate`` (the node's parameter range too).
RATE_BOUNDS = (1e-3, 1e4)
#: Upper bound of ``start_offset_s`` and ``skip_empty_s``, s (the node's parameter range too).
SECONDS_MAX = 1e12
#: Messages handed out by one ``step`` at most, so a late or fast replay keeps its executor responsive.
DEFAULT_BATCH = 1000


@dataclass(frozen=True)
class ReplayConfig:
    """How to replay.

    Attributes
    ----------
    rate
        Playback speed relative to the recording (2.0 = twice as fast), in ``RATE_BOUNDS``.
    start_offset_s
        Start this many seconds (of log time) after the bag's first message; >= 0.
    loop
        Start over when the playlist ends, until stopped.
    topics
        Replay only these topics; empty: every topic of the bag.
    skip_empty_s
        Skip stretches of log time longer than this with no message, s; 0: never skip.
    """

    rate: float = 1.0
    start_offset_s: float = 0.0
    loop: bool = False
    topics: tuple[str, ...] = ()
    skip_empty_s: float = 10.0

    def __post_init__(self) -> None:
        require_range("rate", self.rate, *RATE_BOUNDS, "replay")
        require_range("start_offset_s", self.start_offset_s, 0.0, SECONDS_MAX, "replay")
        require_range("skip_empty_s", self.skip_empty_s, 0.0, SECONDS_MAX, "replay")
        if not all(isinstance(t, str) and t for t in self.topics):
            raise ConfigError(f"replay.topics must be non-empty topic names, got {list(self.topics)!r}")


@dataclass(frozen=True)
class RawMessage:
    """One recorded message: its topic, log time (ns) and CDR bytes as recorded."""

    topic: str
    log_time_ns: int
    data: bytes


@dataclass(frozen=True, eq=False)
class Recording:
    """The messages of a bag to replay.

    Attributes
    ----------
    source
        The bag folder (or ``.mcap`` file) read.
    topics
        ``{topic: type name}`` of the topics replayed.
    messages
        In log-time order; messages logged at the same time keep their order in the file.
    integrity
        How the bag was read and how many messages were lost.
    """

    source: Path
    topics: Mapping[str, str]
    messages: tuple[RawMessage, ...]
    integrity: BagIntegrity

    @property
    def latched_topics(self) -> frozenset[str]:
        """Topics republished transient-local (late joiners get the last message): those of type ``Path``."""
        return frozenset(t for t, ty in self.topics.items() if ty == PATH_TYPE)

    @property
    def duration_s(self) -> float:
        """Log time from the first to the last message, s."""
        return (self.messages[-1].log_time_ns - self.messages[0].log_time_ns) / NS_PER_S

    def counts(self) -> dict[str, int]:
        """Messages per topic."""
        counts = dict.fromkeys(self.topics, 0)
        for message in self.messages:
            counts[message.topic] += 1
        return counts

    def describe(self) -> str:
        """One line for people: what will be replayed, and whether the bag was intact."""
        return (f"{len(self.messages)} messages on {len(self.topics)} topics over {self.duration_s:.3f} s "
                f"of log time from {self.source}; bag {self.integrity.describe()}")


class _TopicChoice:
    """Topic filter for the reader that remembers every topic of the bag it was asked about."""

    def __init__(self, topics: Collection[str]) -> None:
        self.topics = frozenset(topics)
        self.seen: set[str] = set()

    def __call__(self, topic: str) -> bool:
        self.seen.add(topic)
        return not self.topics or topic in self.topics


def load_recording(path: str | Path, topics: Collection[str] = ()) -> Recording:
    """Read a bag's raw messages for replay.

    Parameters
    ----------
    path
        Bag folder (or its ``.mcap`` file); a damaged file gives its readable prefix.
    topics
        Topics to replay; empty: all.

    Raises
    ------
    BagError
        The bag is missing or unreadable, lacks one of ``topics``, or holds no message to replay.
    """
    source = locate(Path(path))
    choice = _TopicChoice(topics)
    raw, integrity = read_raw(source, choice)
    missing = sorted(choice.topics - set(raw.msgtypes))
    if missing:
        raise BagError(f"bag {path} has no topics {missing}; it has {sorted(choice.seen)}")
    in_file_order = [RawMessage(topic, int(t_ns), bytes(data)) for topic, t_ns, data in raw.in_read_order()]
    messages = tuple(sorted(in_file_order, key=lambda m: m.log_time_ns))  # stable: ties keep the file order
    if not messages:
        raise BagError(f"bag {path} holds no message to replay on {sorted(raw.msgtypes)}; "
                       f"bag {integrity.describe()}")
    return Recording(Path(path), dict(sorted(raw.msgtypes.items())), messages, integrity)


def skip_empty(offsets_ns: Sequence[int], skip_empty_ns: int) -> tuple[list[int], int]:
    """Cut every gap longer than ``skip_empty_ns`` between successive offsets to zero (0: keep all).

    Returns the new offsets (ns, same length) and the log time skipped in all, ns.
    """
    shifted, skipped_ns = [], 0
    previous = offsets_ns[0] if offsets_ns else 0
    for offset in offsets_ns:
        if skip_empty_ns and offset - previous > skip_empty_ns:
            skipped_ns += offset - previous
        shifted.append(offset - skipped_ns)
        previous = offset
    return shifted, skipped_ns


def _playlist(recording: Recording, start_offset_s: float) -> tuple[list[RawMessage], list[int]]:
    """Messages from the start offset on (led by the latched ones skipped) and their offsets from it, ns."""
    start_ns = recording.messages[0].log_time_ns + round(start_offset_s * NS_PER_S)
    latched = recording.latched_topics
    carried: dict[str, RawMessage] = {}
    kept: list[RawMessage] = []
    for message in recording.messages:
        if message.log_time_ns >= start_ns:
            kept.append(message)
        elif message.topic in latched:
            carried[message.topic] = message
    if not kept:
        raise ConfigError(f"replay.start_offset_s must be <= {recording.duration_s} (the bag's log-time span), "
                          f"got {start_offset_s}")
    offsets = [0] * len(carried) + [m.log_time_ns - start_ns for m in kept]
    return [*carried.values(), *kept], offsets


class ReplaySchedule:
    """Which messages are due when: maps log time to wall time (s since playback started).

    Parameters
    ----------
    recording
        The messages, in log-time order.
    config
        Rate, start offset and loop (its ``topics`` were applied when loading).

    Raises
    ------
    ConfigError
        The start offset lies past the bag's last message.
    """

    def __init__(self, recording: Recording, config: ReplayConfig) -> None:
        self.config = config
        #: Timeline time of the playlist's start: the bag's first log time plus the start offset, ns.
        self.origin_ns = recording.messages[0].log_time_ns + round(config.start_offset_s * NS_PER_S)
        self._messages, offsets_ns = _playlist(recording, config.start_offset_s)
        self._offsets_ns, skipped_ns = skip_empty(offsets_ns, round(config.skip_empty_s * NS_PER_S))
        #: Log time skipped as empty, per pass, s.
        self.skipped_s = skipped_ns / NS_PER_S
        #: Wall time one pass through the playlist takes, s.
        self.pass_s = self._offsets_ns[-1] / NS_PER_S / config.rate
        self.reset()

    def describe(self) -> str:
        """One line for people: messages, duration of a pass at the rate, what is skipped."""
        skipped = f", {self.skipped_s:.3f} s of empty log time skipped" if self.skipped_s else ""
        return (f"{len(self._messages)} messages, {self.pass_s:.3f} s per pass at rate {self.config.rate:g}"
                f"{skipped}{' (looping)' if self.config.loop else ''}")

    def reset(self) -> None:
        """Back to the first message of the first pass."""
        self._index = 0
        self.passes = 0
        self.published = 0
        self.max_late_s = 0.0

    @property
    def done(self) -> bool:
        """True once every message is handed out (never with ``loop``)."""
        return self._index >= len(self._messages)

    def due_s(self) -> float | None:
        """Wall time at which the next message is due, s; ``None`` when done."""
        if self.done:
            return None
        return self.passes * self.pass_s + self._offsets_ns[self._index] / NS_PER_S / self.config.rate

    def wait_s(self, elapsed_s: float) -> float | None:
        """Time from ``elapsed_s`` until the next message is due (0 if overdue); ``None`` when done."""
        due = self.due_s()
        return None if due is None else max(due - elapsed_s, 0.0)

    def step(self, elapsed_s: float, limit: int = DEFAULT_BATCH) -> list[RawMessage]:
        """The messages due by ``elapsed_s`` (s since playback started), in order, at most ``limit``."""
        due_now: list[RawMessage] = []
        while len(due_now) < limit:
            due = self.due_s()
            if due is None or due > elapsed_s:
                break
            due_now.append(self._messages[self._index])
            self.max_late_s = max(self.max_late_s, elapsed_s - due)
            self._advance()
        self.published += len(due_now)
        return due_now

    def time_range_ns(self) -> tuple[int, int]:
        """First and last timeline time of one pass, ns: log time from :attr:`origin_ns`, empty stretches skipped."""
        return self.origin_ns, self.origin_ns + self._offsets_ns[-1]

    def time_ns(self, elapsed_s: float) -> int:
        """Timeline time at schedule time ``elapsed_s``, ns (within the pass when looping; at most the last)."""
        span_ns = self._offsets_ns[-1]
        offset_ns = round(elapsed_s * self.config.rate * NS_PER_S)
        if self.config.loop and span_ns:
            return self.origin_ns + offset_ns % span_ns
        return self.origin_ns + min(max(offset_ns, 0), span_ns)

    def seek(self, time_ns: int) -> float:
        """Go to the first message at or after timeline time ``time_ns`` (clamped to the pass) in the current pass;
        returns the schedule time that point is due at, s (continue the clock from there)."""
        offset_ns = min(max(int(time_ns) - self.origin_ns, 0), self._offsets_ns[-1])
        self._index = bisect_left(self._offsets_ns, offset_ns)
        return self.passes * self.pass_s + offset_ns / NS_PER_S / self.config.rate

    def _advance(self) -> None:
        self._index += 1
        if self.done and self.config.loop:
            self._index = 0
            self.passes += 1


def replay_summary(schedule: ReplaySchedule, recording: Recording) -> tuple[bool, str, dict[str, str]]:
    """(ok, one line, key values) for the end of a replay: what was published, what the bag had lost."""
    values = {"published": str(schedule.published), "max_late_s": f"{schedule.max_late_s:.6f}",
              "lost": lost_count(recording.integrity)}
    text = (f"replay finished: {schedule.published} messages published, at most {1e3 * schedule.max_late_s:.3f} ms "
            f"late; bag {recording.integrity.describe()}")
    return recording.integrity.complete, text, values


def lost_count(integrity: BagIntegrity) -> str:
    """Messages the bag lost in all, as text: a number, or ``unknown``."""
    lost = integrity.lost
    return "unknown" if lost is None else str(sum(lost.values()))


def topics_of(values: Sequence[str]) -> tuple[str, ...]:
    """Topic names from a string-array parameter, dropping empty entries (ROS has no empty string array)."""
    return tuple(v for v in values if v)
