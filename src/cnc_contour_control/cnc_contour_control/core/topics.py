"""The topics of the suite: names, message types, QoS kinds, which carry one message per tick (ROS-free).

Every node, the runner, the recorder and the bag reader take topic names and
types from here; nothing else spells them. Names are relative to the run's
namespace (default ``/cnc``) unless they start with ``/``. QoS kinds:

``lockstep``
    reliable, volatile, deep (nothing dropped while a stage is busy);
``latched``
    reliable, transient-local, depth 1 (late joiners get the last message);
``status``
    reliable, volatile, depth 100 (``/diagnostics``).

The run-finished protocol: the plant publishes one OK status on
``/diagnostics`` whose message is :data:`RUN_FINISHED` and whose value
:data:`TICKS_KEY` counts the ticks it published; a recorder is complete once
every per-tick topic holds that many messages.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from cnc_contour_control.core.errors import ConfigError

#: Status message announcing the end of a run; its value :data:`TICKS_KEY` counts the ticks published.
RUN_FINISHED = "run finished"
TICKS_KEY = "ticks"
#: Key of the run id in every node's statuses (two runs in one domain tell theirs apart).
RUN_ID_KEY = "run_id"
#: The default namespace of the suite's topics.
DEFAULT_NAMESPACE = "/cnc"
QOS_KINDS = ("lockstep", "latched", "status")


@dataclass(frozen=True)
class Topic:
    """One topic of the suite.

    Attributes
    ----------
    name : str
        Relative to the namespace unless absolute; ``{axis}`` in a per-axis topic.
    type_name : str
        ``pkg/msg/Name``.
    qos : str
        One of :data:`QOS_KINDS`.
    per_tick : bool
        One message per lockstep tick (the recorder's completeness, the bag's verdict).
    """

    name: str
    type_name: str
    qos: str
    per_tick: bool = False

    @property
    def per_axis(self) -> bool:
        """True for a topic with one instance per axis (``servo/{axis}/command``)."""
        return "{axis}" in self.name

    def names(self, axes: Iterable[str]) -> tuple[str, ...]:
        """The concrete (relative) names: one per axis for a per-axis topic."""
        return tuple(self.name.format(axis=a) for a in axes) if self.per_axis else (self.name,)


JOINT_STATES = Topic("joint_states", "sensor_msgs/msg/JointState", "lockstep", per_tick=True)
REFERENCE = Topic("reference", "cnc_contour_interfaces/msg/Reference", "lockstep", per_tick=True)
PATH = Topic("path", "cnc_contour_interfaces/msg/Path", "latched")
COMMAND = Topic("servo/{axis}/command", "cnc_contour_interfaces/msg/AxisCommand", "lockstep", per_tick=True)
CONTOUR_ERROR = Topic("contour_error", "cnc_contour_interfaces/msg/ContourError", "lockstep", per_tick=True)
COMPENSATION = Topic("compensation", "cnc_contour_interfaces/msg/Compensation", "lockstep", per_tick=True)
FEED_OVERRIDE = Topic("feed_override", "cnc_contour_interfaces/msg/FeedOverride", "lockstep", per_tick=True)
CUTTING_FORCE = Topic("cutting_force", "geometry_msgs/msg/WrenchStamped", "lockstep", per_tick=True)
#: The tool position of a plant with machine faults (``name``: axes, ``position`` [m]; what a ballbar measures).
TOOL_POSITION = Topic("tool_position", "sensor_msgs/msg/JointState", "lockstep", per_tick=True)
CLOCK = Topic("/clock", "rosgraph_msgs/msg/Clock", "lockstep")
DIAGNOSTICS = Topic("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", "status")

#: Every topic of the suite by its (relative) name pattern.
TOPICS: dict[str, Topic] = {t.name: t for t in (JOINT_STATES, REFERENCE, PATH, COMMAND, CONTOUR_ERROR, COMPENSATION,
                                                 FEED_OVERRIDE, CUTTING_FORCE, TOOL_POSITION, CLOCK, DIAGNOSTICS)}


def topic(name: str) -> Topic:
    """The topic called ``name`` (its pattern, e.g. ``servo/{axis}/command``); an error lists the valid ones."""
    if name not in TOPICS:
        raise ConfigError(f"topic must be one of {sorted(TOPICS)}, got {name!r}")
    return TOPICS[name]


def command_topic(axis: str) -> str:
    """The relative command topic of ``axis``."""
    return COMMAND.name.format(axis=axis)


def qualify(namespace: str, name: str) -> str:
    """``name`` under ``namespace`` unless it is absolute."""
    return name if name.startswith("/") else f"{namespace.rstrip('/')}/{name}"


def relative(namespace: str, name: str) -> str:
    """The name relative to ``namespace`` (absolute names outside it stay as they are)."""
    prefix = namespace.rstrip("/") + "/"
    return name[len(prefix):] if name.startswith(prefix) else name


def type_of(name: str, axes: Iterable[str] = ()) -> str:
    """The message type of a relative topic name (a per-axis name matched for ``axes``)."""
    if name in TOPICS:
        return TOPICS[name].type_name
    for t in TOPICS.values():
        if t.per_axis and name in t.names(axes):
            return t.type_name
    raise ConfigError(f"{name!r} is not a topic of the suite; topics are {sorted(TOPICS)}")
