"""What a run records: topics and their types, log times, and when a recording is complete (ROS-free)."""
from __future__ import annotations

import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from cnc_contour_control.lockstep import join_ns

#: Topics of a run (relative to the namespace) and their types; command topics are per axis.
RUN_TOPICS: dict[str, str] = {
    "joint_states": "sensor_msgs/msg/JointState",
    "reference": "cnc_contour_interfaces/msg/Reference",
    "path": "cnc_contour_interfaces/msg/Path",
    "contour_error": "cnc_contour_interfaces/msg/ContourError",
    "compensation": "cnc_contour_interfaces/msg/Compensation",
    "feed_override": "cnc_contour_interfaces/msg/FeedOverride",
    "cutting_force": "geometry_msgs/msg/WrenchStamped",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
}
COMMAND_TYPE = "cnc_contour_interfaces/msg/AxisCommand"
#: Topics that carry one message per tick in lockstep.
LOCKSTEP_TOPICS = ("joint_states", "reference", "contour_error", "compensation")


def run_topics(namespace: str, axes: Iterable[str], optional: Iterable[str] = ()) -> dict[str, str]:
    """Fully qualified topics of a run with their types: the core graph plus ``optional`` ones."""
    wanted = ["joint_states", "reference", "path", "/clock", "/diagnostics", *optional]
    topics = {qualify(namespace, name): RUN_TOPICS[name] for name in wanted}
    topics.update({qualify(namespace, f"servo/{axis}/command"): COMMAND_TYPE for axis in axes})
    return topics


def qualify(namespace: str, name: str) -> str:
    """``name`` under ``namespace`` unless it is absolute."""
    return name if name.startswith("/") else f"{namespace.rstrip('/')}/{name}"


def header_stamp_ns(cdr: bytes | memoryview) -> int:
    """The leading builtin_interfaces/Time of a CDR message (every recorded type starts with one).

    Used as the log time, so a recording's contents depend only on the run,
    not on when messages happened to arrive.
    """
    sec, nanosec = struct.unpack_from("<iI", cdr, 4)
    return join_ns(sec, nanosec)


@dataclass
class Completion:
    """Decides when every per-tick topic holds all ticks of a finished run."""

    per_tick_topics: tuple[str, ...]
    ticks: int | None = None

    def complete(self, counts: Mapping[str, int]) -> bool:
        """True once the run's end is known and every per-tick topic has ``ticks`` messages."""
        if self.ticks is None:
            return False
        return all(counts.get(topic, 0) >= self.ticks for topic in self.per_tick_topics)

    def missing(self, counts: Mapping[str, int]) -> dict[str, int]:
        """Messages still missing per per-tick topic."""
        target = self.ticks or 0
        return {t: target - counts.get(t, 0) for t in self.per_tick_topics if counts.get(t, 0) < target}


def per_tick_topics(topics: Mapping[str, str], namespace: str) -> tuple[str, ...]:
    """The recorded topics that carry one message per lockstep tick."""
    lockstep = {qualify(namespace, name) for name in LOCKSTEP_TOPICS}
    return tuple(t for t, ty in topics.items() if t in lockstep or ty == COMMAND_TYPE)
