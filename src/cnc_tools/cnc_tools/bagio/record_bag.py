"""A run record written as the bag the node graph would have recorded (engine runs get a bag too).

Every series of the record goes to its topic (names and types from
:mod:`cnc_contour_control.core.topics`) with log time = the header stamp, as the
recorder writes them, so :func:`cnc_tools.bagio.bag.read_bag` gives the record
back and ``cnc-contour replay`` republishes an engine run like a graph run.
"""
from __future__ import annotations

import heapq
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.core import topics
from cnc_contour_control.core.lockstep import split_ns
from cnc_tools.bagio.bag import BagWriter
from cnc_tools.bagio.synthetic import path_message
from cnc_tools.bagio.typestore import project_typestore
from cnc_tools.run_record import CommandSeries, RunRecord

FRAME_ID = "machine"


def _header(stamp_ns: int, frame_id: str = FRAME_ID) -> Any:
    types = project_typestore().types
    sec, nanosec = split_ns(stamp_ns)
    return types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                        frame_id=frame_id)


def _joint_states(record: RunRecord) -> Iterator[tuple[int, Any]]:
    make = project_typestore().types[topics.JOINT_STATES.type_name]
    js, names = record.joint_states, list(record.axis_names)
    for k, stamp in enumerate(js.stamp_ns.tolist()):
        yield stamp, make(header=_header(stamp), name=names, position=js.position_m[k].copy(),
                          velocity=js.velocity_m_s[k].copy(), effort=np.zeros(0))


def _references(record: RunRecord) -> Iterator[tuple[int, Any]]:
    make = project_typestore().types[topics.REFERENCE.type_name]
    ref, names = record.reference, list(record.axis_names)
    if ref is None:
        return
    ratio = ref.feed_override_ratio
    programmed = ref.feed_m_s if ref.programmed_feed_m_s is None else ref.programmed_feed_m_s
    for k, stamp in enumerate(ref.stamp_ns.tolist()):
        yield stamp, make(header=_header(stamp), axis_names=names, position_m=ref.position_m[k].copy(),
                          velocity_m_s=ref.velocity_m_s[k].copy(), acceleration_m_s2=ref.acceleration_m_s2[k].copy(),
                          path_length_m=float(ref.path_length_m[k]), segment_index=int(ref.segment_index[k]),
                          feed_m_s=float(ref.feed_m_s[k]), programmed_feed_m_s=float(programmed[k]),
                          feed_override_ratio=1.0 if ratio is None else float(ratio[k]),
                          done=bool(ref.done[k]))


def _commands(series: CommandSeries) -> Iterator[tuple[int, Any]]:
    make = project_typestore().types[topics.COMMAND.type_name]
    s = series
    for k, stamp in enumerate(s.stamp_ns.tolist()):
        yield stamp, make(header=_header(stamp, s.axis_name), axis_name=s.axis_name, law=s.law,
                          command_unit=s.command_unit, command=float(s.command[k]), feedback=float(s.feedback[k]),
                          feedforward=float(s.feedforward[k]), compensation=float(s.compensation[k]),
                          disturbance_estimate=float(s.disturbance_estimate[k]), saturated=bool(s.saturated[k]),
                          error_m=float(s.error_m[k]))


def _estimates(record: RunRecord) -> Iterator[tuple[int, Any]]:
    make, e = project_typestore().types[topics.CONTOUR_ERROR.type_name], record.contour_error
    if e is None:
        return
    for k, stamp in enumerate(e.stamp_ns.tolist()):
        yield stamp, make(header=_header(stamp), axis_names=list(record.axis_names),
                          contour_error_m=float(e.contour_error_m[k]), tracking_error_m=e.tracking_error_m[k].copy(),
                          segment_index=int(e.segment_index[k]), angle_rad=float(e.angle_rad[k]),
                          point_a_m=e.point_a_m[k].copy(), point_b_m=e.point_b_m[k].copy(),
                          window_size=int(e.window_size[k]), window_steps=int(e.window_steps[k]), method=e.method)


def _compensations(record: RunRecord) -> Iterator[tuple[int, Any]]:
    make, c = project_typestore().types[topics.COMPENSATION.type_name], record.compensation
    if c is None:
        return
    for k, stamp in enumerate(c.stamp_ns.tolist()):
        yield stamp, make(header=_header(stamp), axis_names=list(record.axis_names),
                          correction=c.correction[k].copy(), command_unit=c.command_unit, method=c.method,
                          learning=bool(c.learning[k]) if c.learning is not None else False)


def _overrides(record: RunRecord) -> Iterator[tuple[int, Any]]:
    make, o = project_typestore().types[topics.FEED_OVERRIDE.type_name], record.feed_override
    if o is None:
        return
    for k, stamp in enumerate(o.stamp_ns.tolist()):
        yield stamp, make(header=_header(stamp), requested_ratio=float(o.requested_ratio[k]),
                          applied_ratio=float(o.applied_ratio[k]), quantum=0.0)


def _wrenches(record: RunRecord) -> Iterator[tuple[int, Any]]:
    types, w = project_typestore().types, record.cutting_force
    vector, wrench = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Wrench"]
    if w is None:
        return
    for k, stamp in enumerate(w.stamp_ns.tolist()):
        yield stamp, types[topics.CUTTING_FORCE.type_name](
            header=_header(stamp, "tool"), wrench=wrench(force=vector(*map(float, w.force_n[k])),
                                                         torque=vector(*map(float, w.torque_n_m[k]))))


def _tool_positions(record: RunRecord) -> Iterator[tuple[int, Any]]:
    make, p = project_typestore().types[topics.TOOL_POSITION.type_name], record.tool_position
    names = list(record.axis_names)
    if p is None:
        return
    for k, stamp in enumerate(p.stamp_ns.tolist()):
        yield stamp, make(header=_header(stamp), name=names, position=p.position_m[k].copy(),
                          velocity=np.zeros(0), effort=np.zeros(0))


#: Optional series: record field -> (topic, its messages).
_OPTIONAL = {"tool_position": (topics.TOOL_POSITION, _tool_positions),
             "contour_error": (topics.CONTOUR_ERROR, _estimates), "compensation": (topics.COMPENSATION, _compensations),
             "feed_override": (topics.FEED_OVERRIDE, _overrides), "cutting_force": (topics.CUTTING_FORCE, _wrenches)}


def _tagged(order: int, topic: str, stream: Iterator[tuple[int, Any]]) -> Iterator[tuple[int, int, str, Any]]:
    """(stamp, order, topic, message): merged by (stamp, order), the order a tick's topics are published in."""
    for stamp, message in stream:
        yield stamp, order, topic, message


def write_record_bag(record: RunRecord, path: Path, namespace: str = topics.DEFAULT_NAMESPACE) -> Path:
    """Write ``record`` to a new bag folder ``path`` (refused if it exists) and return it."""
    def q(name: str) -> str:
        return topics.qualify(namespace, name)

    streams: dict[str, Iterator[tuple[int, Any]]] = {
        q(topics.JOINT_STATES.name): _joint_states(record), q(topics.REFERENCE.name): _references(record)}
    streams.update({q(topics.command_topic(axis)): _commands(s) for axis, s in record.commands.items()})
    types = {q(topics.PATH.name): topics.PATH.type_name, q(topics.JOINT_STATES.name): topics.JOINT_STATES.type_name,
             q(topics.REFERENCE.name): topics.REFERENCE.type_name}
    types.update({q(topics.command_topic(axis)): topics.COMMAND.type_name for axis in record.commands})
    for field_name, (topic, messages) in _OPTIONAL.items():
        if getattr(record, field_name) is not None:
            streams[q(topic.name)], types[q(topic.name)] = messages(record), topic.type_name
    with BagWriter(path, types) as writer:
        writer.write_message(q(topics.PATH.name), 0, path_message(record.program))
        tagged = [_tagged(order, topic, stream) for order, (topic, stream) in enumerate(streams.items())]
        for stamp, _, name, message in heapq.merge(*tagged, key=lambda item: item[:2]):  # tick order, as recorded
            writer.write_message(name, stamp, message)
    return path
