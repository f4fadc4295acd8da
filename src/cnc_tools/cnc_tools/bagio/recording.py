"""What a run records: topics and their types, log times, and when a recording is complete (ROS-free).

The topic sets come from the stage pipeline (:mod:`cnc_contour_control.core.stages`)
and the one home of topic names (:mod:`cnc_contour_control.core.topics`); nothing
here spells a topic. A run's topics live under its namespace; ``/clock`` and
``/diagnostics`` are absolute in the nodes and the runner remaps them into the
run's namespace, so a bag holds either ``<ns>/clock`` (runs since isolation)
or ``/clock`` (older bags, launch-file runs); :func:`run_namespace` finds the
run's namespace in either.
"""
from __future__ import annotations

import re
import struct
from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass

from cnc_contour_control.core import topics as t
from cnc_contour_control.core.errors import BagError
from cnc_contour_control.core.lockstep import join_ns
from cnc_contour_control.core.stages import pipeline


def run_topics(namespace: str, axes: Sequence[str], optional_stages: Collection[str] = (),
               optional_outputs: Collection[str] = ()) -> dict[str, str]:
    """Fully qualified topics a recorder of the run records, with their types (absolute ones stay absolute)."""
    recorded = pipeline(axes, optional_stages, optional_outputs).recorded_topics()
    return {t.qualify(namespace, name): type_name for name, type_name in recorded.items()}


def per_tick_topics(namespace: str, axes: Sequence[str], optional_stages: Collection[str] = (),
                    optional_outputs: Collection[str] = ()) -> tuple[str, ...]:
    """Fully qualified topics that carry one message per tick in the run."""
    per_tick = pipeline(axes, optional_stages, optional_outputs).per_tick_topics()
    return tuple(t.qualify(namespace, name) for name in per_tick)


def is_latched(type_name: str) -> bool:
    """True for the types published transient-local (the program's path)."""
    return any(topic.qos == "latched" and topic.type_name == type_name for topic in t.TOPICS.values())


def is_wall_stamped(type_name: str) -> bool:
    """True for the types a recorder logs at the run's latest time, not at their own stamp (``/diagnostics``: a
    status is stamped at its node's last tick, which may lag the run)."""
    return type_name == t.DIAGNOSTICS.type_name


def run_namespace(topic_names: Iterable[str]) -> str:
    """The namespace of the run recorded in a bag: where its ``joint_states`` topic lives.

    Raises
    ------
    BagError
        The bag holds ``joint_states`` of several namespaces (several runs).
    """
    suffix = "/" + t.JOINT_STATES.name
    found = sorted({name[: -len(suffix)] or "/" for name in topic_names if name.endswith(suffix)})
    if len(found) > 1:
        raise BagError(f"bag holds {t.JOINT_STATES.name} of several runs {found}; choose one with namespace=")
    return found[0] if found else t.DEFAULT_NAMESPACE


def in_some_namespace(topic_name: str, patterns: Iterable[str]) -> bool:
    """True if ``topic_name`` is one of the relative topic ``patterns`` (``{axis}`` for any axis) under any
    namespace."""
    return any(re.fullmatch(r"(/[^/]+)*/" + re.escape(p).replace(r"\{axis\}", "[^/]+"), topic_name) for p in patterns)


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
        return {topic: target - counts.get(topic, 0) for topic in self.per_tick_topics if counts.get(topic, 0) < target}
