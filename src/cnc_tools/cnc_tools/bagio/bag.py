"""Bag I/O, the public facade: write MCAP bags in the rosbag2 layout, read a recorded run back as arrays.

A bag is a folder ``<name>/`` holding ``metadata.yaml`` (rosbag2 version 9 with
the per-topic message counts) and ``<name>.mcap`` (ros2 profile, ``ros2msg``
schemas, CDR messages in CRC-checked 64 KiB chunks, message indexes and a summary), written by
``rosbags.rosbag2.Writer`` on :mod:`cnc_tools.bagio.mcap_storage` (the ``mcap`` library's bytes, written by
:mod:`cnc_tools.bagio.mcap_writer`; each message goes straight to it, rosbags' counts are kept here);
``ros2 bag``, Foxglove, ``rosbags`` and ``mcap`` read it.

Reading (:mod:`cnc_tools.bagio.raw_bag`) goes through ``rosbags``' ``AnyReader`` (the
file's index). When that fails (a truncated or damaged file) the salvage scan
(:mod:`cnc_tools.bagio.mcap_salvage`) keeps every intact message of the readable
prefix. ``BagIntegrity`` says how the file was read and how many messages were
lost, or that the loss is unknown. A damaged file is never reported complete.
This module decodes the raw messages into a :class:`RecordedRun`
(:mod:`cnc_tools.run_record`). No rclpy: the recorder hands over raw CDR bytes.
"""
from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, cast

import numpy as np
from rosbags.interfaces import Connection, Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.typesys.store import Typestore

from cnc_contour_control.core import topics
from cnc_contour_control.core.errors import BagError, CncError
from cnc_contour_control.core.lockstep import NS_PER_S
from cnc_contour_control.motion.geometry import Program
from cnc_tools.bagio.mcap_storage import CheckedMcapStorage, with_ros_distro
from cnc_tools.bagio.path_message import program_from_path
from cnc_tools.bagio.raw_bag import RawBag, locate, read_raw
from cnc_tools.bagio.recording import in_some_namespace, run_namespace
from cnc_tools.bagio.typestore import ColumnBlock, decode_columns, project_typestore
from cnc_tools.run_record import (
    BagIntegrity,
    CommandSeries,
    CompensationSeries,
    EstimateSeries,
    FeedOverrideSeries,
    FloatArray,
    ForceSeries,
    IntArray,
    JointStateSeries,
    RecordedRun,
    ReferenceSeries,
    RunRecord,
    ToolPositionSeries,
)

__all__ = [
    "PATH_TYPE", "TRANSIENT_LOCAL_QOS", "BagIntegrity", "BagWriter", "CommandSeries", "FloatArray", "IntArray",
    "JointStateSeries", "RecordedRun", "ReferenceSeries", "TopicNames", "read_bag",
]

PATH_TYPE = topics.PATH.type_name
_NO_TIME = QosTime(sec=0, nsec=0)
#: QoS offered for latched topics (``/cnc/path``): ``ros2 bag play`` republishes them transient-local.
TRANSIENT_LOCAL_QOS = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
                          _NO_TIME, _NO_TIME, QosLiveliness.AUTOMATIC, _NO_TIME, False)
#: QoS the suite's nodes offer on per-tick topics (``lockstep``: reliable, volatile, depth 1000).
LOCKSTEP_QOS = Qos(QosHistory.KEEP_LAST, 1000, QosReliability.RELIABLE, QosDurability.VOLATILE,
                   _NO_TIME, _NO_TIME, QosLiveliness.AUTOMATIC, _NO_TIME, False)
#: QoS offered on ``/diagnostics`` (``status``: reliable, volatile, depth 100).
STATUS_QOS = Qos(QosHistory.KEEP_LAST, 100, QosReliability.RELIABLE, QosDurability.VOLATILE,
                 _NO_TIME, _NO_TIME, QosLiveliness.AUTOMATIC, _NO_TIME, False)
_DIAGNOSTICS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"


class _CheckedWriter(Writer):
    """rosbags' rosbag2 writer on :class:`CheckedMcapStorage` (chunk CRCs, small chunks)."""

    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: CheckedMcapStorage}


# =========================================================================== writing
class BagWriter:
    """Write raw CDR messages to a new MCAP bag folder in the rosbag2 layout.

    Parameters
    ----------
    path
        Bag folder to create; it must not exist (never overwritten).
    topics
        ``{topic: type_name}``, e.g. ``{"/cnc/joint_states": "sensor_msgs/msg/JointState"}``.
    typestore
        Typestore giving the schemas; default: Jazzy plus ``cnc_contour_interfaces``.
    transient_local_topics
        Topics recorded with a transient-local QoS profile; default: those of type ``Path``.
    """

    #: The rosbags writer class (its MCAP storage: :class:`CheckedMcapStorage`).
    _ROSBAG_WRITER: type[Writer] = _CheckedWriter

    def __init__(self, path: str | Path, topics: Mapping[str, str], *, typestore: Typestore | None = None,
                 transient_local_topics: Collection[str] | None = None) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f"bag folder {self.path} exists already; choose a new path (bags are never overwritten)")
        if not topics:
            raise BagError(f"bag {self.path}: topics must name at least one topic")
        self._store = typestore or project_typestore()
        unknown = {t: ty for t, ty in topics.items() if ty not in self._store.types}
        if unknown:
            raise BagError(f"bag {self.path}: unknown message types {unknown}; not in the Jazzy typestore "
                           "nor in cnc_contour_interfaces")
        self._latched = transient_local_topics
        self._writer: Writer | None = self._ROSBAG_WRITER(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._connections: dict[str, Connection] = {}
        self._closed_counts: dict[str, int] = {}
        self._direct: dict[str, tuple[Callable[..., None], int, list[int]]] = {}  # topic -> write, channel, [count]
        self._min_ns, self._max_ns = 2**63 - 1, 0
        self.topics: dict[str, str] = {}
        try:
            self._writer.open()
        except (WriterError, OSError) as err:
            raise BagError(f"cannot create bag {self.path}: {err}") from err
        for topic, msgtype in topics.items():
            self.add_topic(topic, msgtype)

    def add_topic(self, topic: str, type_name: str) -> None:
        """Declare one more topic (before writing to it); transient-local if so declared, or of type ``Path``."""
        if self._writer is None:
            raise BagError(f"bag {self.path} is closed; cannot add {topic}")
        if topic in self._connections or type_name not in self._store.types:
            reason = "is declared already" if topic in self._connections else f"has unknown type {type_name!r}"
            raise BagError(f"bag {self.path}: topic {topic!r} {reason}")
        latched = topic in self._latched if self._latched is not None else type_name == PATH_TYPE
        qos = TRANSIENT_LOCAL_QOS if latched else STATUS_QOS if type_name == _DIAGNOSTICS_TYPE else LOCKSTEP_QOS
        try:
            self._connections[topic] = connection = self._writer.add_connection(
                topic, type_name, typestore=self._store, offered_qos_profiles=[qos])
        except WriterError as err:
            raise BagError(f"bag {self.path}: cannot add topic {topic!r}: {err}") from err
        self.topics[topic] = type_name
        storage = cast(CheckedMcapStorage, self._writer.storage)
        self._direct[topic] = (storage.write_channel, storage.channel_id(connection), [0])

    def write(self, topic: str, timestamp_ns: int, cdr_bytes: bytes | memoryview) -> None:
        """Append one serialised message; ``timestamp_ns`` is the log time (ns).

        Straight to the storage's writer: rosbags' counts and time range are
        kept here and handed to rosbags at :meth:`close` (same ``metadata.yaml``).
        """
        direct = self._direct.get(topic)
        if direct is None or self._writer is None:
            raise BagError(f"bag {self.path} is closed; cannot write {topic}" if self._writer is None else
                           f"bag {self.path}: topic {topic!r} was not declared; declared: {sorted(self._connections)}")
        write, channel_id, count = direct
        stamp_ns = int(timestamp_ns)
        write(channel_id, stamp_ns, cdr_bytes, stamp_ns)
        count[0] += 1
        if stamp_ns < self._min_ns:
            self._min_ns = stamp_ns
        if stamp_ns > self._max_ns:
            self._max_ns = stamp_ns

    def write_message(self, topic: str, timestamp_ns: int, message: object) -> None:
        """Serialise ``message`` (a typestore message object) to CDR and append it."""
        self.write(topic, timestamp_ns, self._store.serialize_cdr(message, self.topics.get(topic, "")))

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written so far, per topic."""
        if self._writer is None:
            return dict(self._closed_counts)
        return {topic: direct[2][0] for topic, direct in self._direct.items()}

    def flush(self) -> None:
        """Write the messages buffered so far to the file as a complete chunk, and hand them to the OS.

        The writer keeps up to one chunk (``CHUNK_SIZE_BYTES``) in memory; a
        writer killed before :meth:`close` would lose it. After a flush, a killed
        writer leaves a file whose chunks up to here the salvage scan recovers.
        """
        storage = self._writer.storage if self._writer is not None else None
        if not isinstance(storage, CheckedMcapStorage):  # closed, or not open yet
            return
        try:
            storage.flush()
        except OSError as err:
            raise BagError(f"cannot flush bag {self.path}: {err}") from err

    def close(self) -> None:
        """Finish the MCAP summary and write ``metadata.yaml``; calling it again does nothing."""
        if self._writer is None:
            return
        self._closed_counts = self.message_counts
        writer, self._writer = self._writer, None
        for topic, connection in self._connections.items():  # rosbags' bookkeeping, skipped per message
            writer.counts[connection.id] = self._closed_counts[topic]
        writer.min_timestamp = min(writer.min_timestamp, self._min_ns)
        writer.max_timestamp = max(writer.max_timestamp, self._max_ns)
        try:
            writer.close()
            metadata_path = self.path / "metadata.yaml"  # rosbags writes ros_distro: rosbags
            metadata_path.write_text(with_ros_distro(metadata_path.read_text("utf-8")), "utf-8")
        except (WriterError, OSError) as err:
            raise BagError(f"cannot finish bag {self.path}: {err}") from err

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()



# =========================================================================== topics read
#: Topics a run record is decoded from (relative names; ``servo/<axis>/command`` besides).
_DECODED = (topics.JOINT_STATES.name, topics.REFERENCE.name, topics.PATH.name, topics.CONTOUR_ERROR.name,
            topics.COMPENSATION.name, topics.FEED_OVERRIDE.name, topics.CUTTING_FORCE.name,
            topics.TOOL_POSITION.name)


@dataclass(frozen=True)
class TopicNames:
    """The suite's topics (:mod:`cnc_contour_control.core.topics`) under a namespace (default ``/cnc``)."""

    namespace: str = topics.DEFAULT_NAMESPACE

    def topic(self, name: str) -> str:
        """The fully qualified name of the relative topic ``name``."""
        return topics.qualify(self.namespace, name)

    def command_axis(self, topic: str) -> str | None:
        """Axis name of a ``servo/<axis>/command`` topic, else ``None``."""
        head, _, tail = self.topic(topics.COMMAND.name).partition("{axis}")
        inner = topic[len(head):-len(tail)] if topic.startswith(head) and topic.endswith(tail) else ""
        return inner if inner and "/" not in inner else None

    def wanted(self, topic: str, commands: bool) -> bool:
        """True for a topic the run record is decoded from."""
        core = {self.topic(name) for name in _DECODED}
        return topic in core or (commands and self.command_axis(topic) is not None)

    def expected_type(self, topic: str) -> str:
        """The message type the suite publishes on ``topic``."""
        if self.command_axis(topic) is not None:
            return topics.COMMAND.type_name
        return topics.type_of(topics.relative(self.namespace, topic))


# =========================================================================== decoding
@dataclass(frozen=True)
class _Fields:
    """What to decode from one topic: per-axis fields (name -> required), scalars, strings."""

    names_field: str | None = None
    axis_fields: Mapping[str, bool] = field(default_factory=dict)
    scalars: tuple[str, ...] = ()
    strings: tuple[str, ...] = ()


def _blocks(raw: RawBag, topic: str, names: TopicNames) -> list[ColumnBlock]:
    msgtype, expected = raw.msgtypes[topic], names.expected_type(topic)
    if msgtype != expected:
        raise BagError(f"{topic} has type {msgtype!r}, expected {expected!r}")
    try:
        return decode_columns(raw.data[topic], msgtype, raw.typestore or project_typestore())
    except CncError as err:
        raise BagError(f"{topic}: {err}") from err


def _axis_columns(block: ColumnBlock, names_field: str, axis_names: tuple[str, ...], topic: str) -> list[int]:
    names = tuple(block.strings[names_field])
    missing = [a for a in axis_names if a not in names]
    if missing:
        raise BagError(f"{topic} lacks axes {missing} of the path (it has {list(names)})")
    return [names.index(a) for a in axis_names]


def _fill_axes(out: dict[str, np.ndarray], block: ColumnBlock, spec: _Fields, axes: tuple[str, ...],
               topic: str) -> None:
    if spec.names_field is None:
        return
    columns = _axis_columns(block, spec.names_field, axes, topic)
    n_names = len(block.strings[spec.names_field])
    for name, required in spec.axis_fields.items():
        values = block.numbers[name]
        if values.shape[1] == n_names:
            out[name][block.rows] = values[:, columns]
        elif values.shape[1] or required:
            raise BagError(f"{topic}: {name} has {values.shape[1]} values for {n_names} axis names")


def _columns(raw: RawBag, topic: str, spec: _Fields, axes: tuple[str, ...],
             names: TopicNames) -> dict[str, Any]:
    """Decode a topic sorted by header stamp: per-axis fields (N, n_axes), scalars (N,), strings joined by '|'.

    Typed ``Any``: each value is an array or a string by its field, as the series classes take them.
    """
    count = len(raw.data[topic])
    out: dict[str, np.ndarray] = {"stamp_ns": np.zeros(count, np.int64)}
    out.update({name: np.full((count, len(axes)), np.nan) for name in spec.axis_fields})
    strings: dict[str, set[str]] = {name: set() for name in spec.strings}
    needed = {"header.stamp.sec", "header.stamp.nanosec", *spec.axis_fields, *spec.scalars}
    for block in _blocks(raw, topic, names):
        missing = sorted(needed - set(block.numbers) | set(spec.strings) - set(block.strings))
        if missing:
            raise BagError(f"{topic}: the recorded {raw.msgtypes[topic]} has no fields {missing}")
        sec = block.numbers["header.stamp.sec"].astype(np.int64)
        out["stamp_ns"][block.rows] = sec * NS_PER_S + block.numbers["header.stamp.nanosec"].astype(np.int64)
        _fill_axes(out, block, spec, axes, topic)
        for name in spec.scalars:
            out.setdefault(name, np.zeros(count, block.numbers[name].dtype))[block.rows] = block.numbers[name]
        for name in spec.strings:
            strings[name].add(str(block.strings[name]))
    order = np.argsort(out["stamp_ns"], kind="stable")
    return {**{k: v[order] for k, v in out.items()}, **{k: "|".join(sorted(v)) for k, v in strings.items()}}


def _joint_states(raw: RawBag, names: TopicNames, axes: tuple[str, ...]) -> JointStateSeries:
    topic = names.topic(topics.JOINT_STATES.name)
    if not raw.data.get(topic):
        raise BagError(f"bag has no {topic} messages; found {sorted(t for t in raw.data if raw.data[t])}")
    cols = _columns(raw, topic, _Fields("name", {"position": True, "velocity": False}), axes, names)
    return JointStateSeries(cols["stamp_ns"], cols["position"], cols["velocity"])


_REFERENCE = _Fields("axis_names", {"position_m": True, "velocity_m_s": False, "acceleration_m_s2": False},
                     ("path_length_m", "segment_index", "feed_m_s", "done", "feed_override_ratio",
                      "programmed_feed_m_s"))


def _reference(raw: RawBag, names: TopicNames, axes: tuple[str, ...]) -> ReferenceSeries | None:
    topic = names.topic(topics.REFERENCE.name)
    if not raw.data.get(topic):
        return None
    c = _columns(raw, topic, _REFERENCE, axes, names)
    return ReferenceSeries(c["stamp_ns"], c["position_m"], c["velocity_m_s"], c["acceleration_m_s2"],
                           c["path_length_m"], c["segment_index"].astype(np.int64), c["feed_m_s"],
                           c["done"].astype(bool), c["feed_override_ratio"], c["programmed_feed_m_s"])


_COMMAND = _Fields(scalars=("command", "feedback", "feedforward", "compensation", "disturbance_estimate",
                            "saturated", "error_m"), strings=("law", "command_unit"))


def _commands(raw: RawBag, names: TopicNames, axes: tuple[str, ...]) -> dict[str, CommandSeries]:
    series: dict[str, CommandSeries] = {}
    for topic in sorted(raw.data):
        axis = names.command_axis(topic)
        if axis is not None and raw.data[topic]:
            cols = _columns(raw, topic, _COMMAND, axes, names)
            cols["saturated"] = cols["saturated"].astype(bool)
            series[axis] = CommandSeries(axis_name=axis, **cols)
    return series


_ESTIMATE = _Fields("axis_names", {"tracking_error_m": False, "point_a_m": False, "point_b_m": False},
                    ("contour_error_m", "segment_index", "angle_rad", "window_size", "window_steps"), ("method",))
_COMPENSATION = _Fields("axis_names", {"correction": True}, ("learning",), ("command_unit", "method"))
_FEED_OVERRIDE = _Fields(scalars=("requested_ratio", "applied_ratio"))
_XYZ = ("x", "y", "z")
_WRENCH = _Fields(scalars=tuple(f"wrench.{part}.{c}" for part in ("force", "torque") for c in _XYZ))


def _stage_series(raw: RawBag, names: TopicNames, axes: tuple[str, ...]) -> dict[str, object]:
    """The optional series (estimator, compensator, feed override, cutting force, tool position) the bag has."""
    out: dict[str, object] = {}
    topic = names.topic(topics.CONTOUR_ERROR.name)
    if raw.data.get(topic):
        c = _columns(raw, topic, _ESTIMATE, axes, names)
        out["contour_error"] = EstimateSeries(
            c["stamp_ns"], c["contour_error_m"], c["tracking_error_m"], c["segment_index"].astype(np.int64),
            c["angle_rad"], c["point_a_m"], c["point_b_m"], c["window_size"].astype(np.int64),
            c["window_steps"].astype(np.int64), str(c["method"]))
    topic = names.topic(topics.COMPENSATION.name)
    if raw.data.get(topic):
        c = _columns(raw, topic, _COMPENSATION, axes, names)
        out["compensation"] = CompensationSeries(c["stamp_ns"], c["correction"], str(c["command_unit"]),
                                                 c["learning"].astype(bool), str(c["method"]))
    topic = names.topic(topics.FEED_OVERRIDE.name)
    if raw.data.get(topic):
        c = _columns(raw, topic, _FEED_OVERRIDE, axes, names)
        out["feed_override"] = FeedOverrideSeries(c["stamp_ns"], c["requested_ratio"], c["applied_ratio"])
    topic = names.topic(topics.CUTTING_FORCE.name)
    if raw.data.get(topic):
        c = _columns(raw, topic, _WRENCH, axes, names)
        force, torque = (np.column_stack([c[f"wrench.{part}.{x}"] for x in _XYZ]) for part in ("force", "torque"))
        out["cutting_force"] = ForceSeries(c["stamp_ns"], force, torque)
    topic = names.topic(topics.TOOL_POSITION.name)
    if raw.data.get(topic):
        c = _columns(raw, topic, _Fields("name", {"position": True}), axes, names)
        out["tool_position"] = ToolPositionSeries(c["stamp_ns"], c["position"])
    return out


def _program(raw: RawBag, topic: str) -> Program:
    messages = raw.data.get(topic) or []
    if not messages:
        raise BagError(f"bag has no {topic} message: the program geometry is needed to score the run")
    if len({bytes(m) for m in messages}) > 1:
        raise BagError(f"bag holds {len(messages)} different programs on {topic}; record one program per bag")
    store = raw.typestore or project_typestore()
    try:
        return program_from_path(store.deserialize_cdr(messages[0], raw.msgtypes[topic]))
    except CncError as err:
        raise BagError(f"{topic}: the recorded program is invalid: {err}") from err
    except Exception as err:
        raise BagError(f"{topic}: cannot decode the recorded program ({type(err).__name__}: {err})") from err


# =========================================================================== reading
def _run_name(mcap_path: Path, is_dir: bool) -> str:
    """A run's name: ``<scenario>/<start time>`` for a run folder's ``bag/`` (its folder or its ``.mcap``).

    Any other bag is named by its folder, or by its file's stem when a file was given.
    """
    folder = mcap_path.parent
    if folder.name != "bag":
        return folder.name if is_dir else mcap_path.stem
    run_dir = folder.resolve().parent
    return f"{run_dir.parent.name}/{run_dir.name}"


def read_bag(path: str | Path, *, namespace: str | None = None, commands: bool = True) -> RunRecord:
    """Read a recorded run.

    Parameters
    ----------
    path
        Bag folder (or its ``.mcap`` file).
    namespace
        Namespace of the suite's topics; default: the run's, where the bag's ``joint_states`` lives
        (``/cnc`` in older bags, ``/cnc/<run id>`` since runs are isolated).
    commands
        Also decode ``servo/<axis>/command``; scoring does not need them.

    Returns
    -------
    RecordedRun
        Arrays sorted by header stamp, with the ``BagIntegrity`` of the file.

    Raises
    ------
    BagError
        The bag is missing or unreadable, or lacks the path, joint states, or an axis of the path.
    """
    source = locate(Path(path))
    if namespace is None:
        patterns = (*_DECODED, *((topics.COMMAND.name,) if commands else ()))
        raw, integrity = read_raw(source, lambda topic: in_some_namespace(topic, patterns))
        names = TopicNames(run_namespace(raw.msgtypes))
    else:
        names = TopicNames(namespace)
        raw, integrity = read_raw(source, lambda topic: names.wanted(topic, commands))
    try:
        program = _program(raw, names.topic(topics.PATH.name))
        axes = tuple(program.axis_names)
        return RunRecord(
            name=_run_name(source.mcap_path, Path(path).is_dir()),
            source=Path(path), program=program,
            joint_states=_joint_states(raw, names, axes),
            reference=_reference(raw, names, axes),
            commands=_commands(raw, names, axes) if commands else {}, integrity=integrity,
            **_stage_series(raw, names, axes))  # type: ignore[arg-type]  # each series under its RunRecord field
    except BagError as err:
        raise BagError(f"{path}: {err}" + ("" if integrity.complete else f" [{integrity.describe()}]")) from err
