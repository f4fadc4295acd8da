"""Bag I/O: write MCAP bags in the rosbag2 layout, read a recorded run back as arrays.

A bag is a folder ``<name>/`` holding ``metadata.yaml`` (rosbag2 version 9 with
the per-topic message counts) and ``<name>.mcap`` (ros2 profile, ``ros2msg``
schemas, CDR messages in chunks, message indexes and a summary), written by
``rosbags.rosbag2.Writer``; ``ros2 bag``, Foxglove, ``rosbags`` and ``mcap`` read it.

Reading goes through ``rosbags``' ``AnyReader`` (the file's index). When that
fails (a truncated or damaged file) the reader scans the file record by record
and keeps every intact message of the readable prefix. ``BagIntegrity`` says how
the file was read and how many messages were lost, or that the loss is unknown.
A damaged file is never reported complete. No rclpy: the recorder hands over raw
CDR bytes.
"""
from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType

import numpy as np
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Connection, Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore
from ruamel.yaml import YAML

from cnc_contour_control.errors import BagError, CncError
from cnc_contour_control.geometry import ArcSegment, LineSegment, Program
from cnc_tools.typestore import ColumnBlock, decode_columns, project_typestore

PATH_TYPE = "cnc_contour_interfaces/msg/Path"
_NO_TIME = QosTime(sec=0, nsec=0)
#: QoS offered for latched topics (``/cnc/path``): ``ros2 bag play`` republishes them transient-local.
TRANSIENT_LOCAL_QOS = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
                          _NO_TIME, _NO_TIME, QosLiveliness.AUTOMATIC, _NO_TIME, False)
FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


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
        self._writer: Writer | None = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._connections: dict[str, Connection] = {}
        self._closed_counts: dict[str, int] = {}
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
        try:
            self._connections[topic] = self._writer.add_connection(
                topic, type_name, typestore=self._store, offered_qos_profiles=[TRANSIENT_LOCAL_QOS] if latched else [])
        except WriterError as err:
            raise BagError(f"bag {self.path}: cannot add topic {topic!r}: {err}") from err
        self.topics[topic] = type_name

    def write(self, topic: str, timestamp_ns: int, cdr_bytes: bytes | memoryview) -> None:
        """Append one serialised message; ``timestamp_ns`` is the log time (ns)."""
        if self._writer is None:
            raise BagError(f"bag {self.path} is closed; cannot write {topic}")
        connection = self._connections.get(topic)
        if connection is None:
            raise BagError(f"bag {self.path}: topic {topic!r} was not declared; declared: {sorted(self._connections)}")
        self._writer.write(connection, int(timestamp_ns), cdr_bytes)

    def write_message(self, topic: str, timestamp_ns: int, message: object) -> None:
        """Serialise ``message`` (a typestore message object) to CDR and append it."""
        self.write(topic, timestamp_ns, self._store.serialize_cdr(message, self.topics.get(topic, "")))

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written so far, per topic."""
        if self._writer is None:
            return dict(self._closed_counts)
        return {topic: self._writer.counts[conn.id] for topic, conn in self._connections.items()}

    def close(self) -> None:
        """Finish the MCAP summary and write ``metadata.yaml``; calling it again does nothing."""
        if self._writer is None:
            return
        self._closed_counts = self.message_counts
        writer, self._writer = self._writer, None
        try:
            writer.close()
        except (WriterError, OSError) as err:
            raise BagError(f"cannot finish bag {self.path}: {err}") from err

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()


# =========================================================================== recorded run
@dataclass(frozen=True)
class BagIntegrity:
    """How a bag was read and what, if anything, is missing.

    Attributes
    ----------
    complete
        True only when the file was read through its intact index and every topic
        read holds as many messages as expected.
    method
        ``"index"`` (rosbags through the MCAP summary) or ``"scan"`` (record-by-record salvage).
    found
        Messages read per topic (the topics ``read_bag`` decodes).
    expected
        Messages the writer recorded per topic, or ``None`` when unknown.
    expected_source
        ``"metadata.yaml"``, ``"mcap summary"`` or ``"unknown"``.
    problems
        What went wrong, in words; empty for a complete bag.
    """

    complete: bool
    method: str
    found: Mapping[str, int]
    expected: Mapping[str, int] | None
    expected_source: str
    problems: tuple[str, ...] = ()

    @property
    def lost(self) -> dict[str, int] | None:
        """Messages missing per topic (expected - found), or ``None`` when the count is unknown."""
        if self.expected is None:
            return None
        return {topic: max(self.expected.get(topic, 0) - count, 0) for topic, count in self.found.items()}

    def describe(self) -> str:
        """One line for people: complete, or what was lost."""
        if self.complete:
            notes = "".join(f"; {p}" for p in self.problems)
            return f"complete ({sum(self.found.values())} messages read through the index{notes})"
        lost = self.lost
        if lost is None:
            loss = "count of lost messages unknown (no metadata.yaml, no MCAP summary)"
        elif any(lost.values()):
            loss = f"{sum(lost.values())} messages lost ({', '.join(f'{t}: {n}' for t, n in lost.items() if n)})"
        else:
            loss = f"no messages lost (all {sum(self.found.values())} expected were recovered)"
        return f"INCOMPLETE, read by {self.method}: {loss}; " + "; ".join(self.problems)


@dataclass(frozen=True, eq=False)
class JointStateSeries:
    """Measured axis states. ``stamp_ns`` (N,) int64 header stamps; arrays (N, n_axes) in run axis order."""

    stamp_ns: IntArray
    position_m: FloatArray
    velocity_m_s: FloatArray


@dataclass(frozen=True, eq=False)
class ReferenceSeries:
    """Interpolated references: per-axis arrays (N, n_axes); scalars (N,)."""

    stamp_ns: IntArray
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray
    path_length_m: FloatArray
    segment_index: IntArray
    feed_m_s: FloatArray
    done: NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class CommandSeries:
    """One axis's servo commands (N,) in ``command_unit``; ``error_m`` the following error, m."""

    axis_name: str
    law: str
    command_unit: str
    stamp_ns: IntArray
    command: FloatArray
    feedback: FloatArray
    feedforward: FloatArray
    compensation: FloatArray
    disturbance_estimate: FloatArray
    saturated: NDArray[np.bool_]
    error_m: FloatArray


@dataclass(frozen=True, eq=False)
class RecordedRun:
    """A run read from a bag: program geometry, measured and reference trajectories, commands."""

    name: str
    source: Path
    program: Program
    joint_states: JointStateSeries
    reference: ReferenceSeries | None
    commands: Mapping[str, CommandSeries]
    integrity: BagIntegrity

    @property
    def axis_names(self) -> tuple[str, ...]:
        """Axis order of every per-axis array (the program's)."""
        return tuple(self.program.axis_names)


@dataclass(frozen=True)
class TopicNames:
    """Topic names under a namespace (default ``/cnc``)."""

    namespace: str = "/cnc"

    def topic(self, name: str) -> str:
        return f"{self.namespace.rstrip('/')}/{name}"

    def command_axis(self, topic: str) -> str | None:
        """Axis name of a ``servo/<axis>/command`` topic, else ``None``."""
        head, tail = self.topic("servo/"), "/command"
        inner = topic[len(head):-len(tail)] if topic.startswith(head) and topic.endswith(tail) else ""
        return inner if inner and "/" not in inner else None

    def wanted(self, topic: str, commands: bool) -> bool:
        core = {self.topic("joint_states"), self.topic("reference"), self.topic("path")}
        return topic in core or (commands and self.command_axis(topic) is not None)


# =========================================================================== locating and metadata
@dataclass(frozen=True)
class _Source:
    mcap_path: Path
    metadata_counts: Mapping[str, int] | None
    problems: tuple[str, ...]


def _metadata_counts(folder: Path) -> tuple[dict[str, int] | None, list[str], tuple[str, ...]]:
    """Per-topic counts and file names from ``metadata.yaml``; ``None`` and a note when unusable."""
    meta_path = folder / "metadata.yaml"
    if not meta_path.is_file():
        return None, [], (f"{meta_path} is missing",)
    try:
        info = YAML(typ="safe").load(meta_path.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
        counts = {str(t["topic_metadata"]["name"]): int(t["message_count"]) for t in info["topics_with_message_count"]}
        return counts, [Path(str(p)).name for p in info.get("relative_file_paths", [])], ()
    except Exception as err:  # noqa: BLE001 - any malformed YAML is reported, never raised raw
        return None, [], (f"{meta_path} is unreadable ({type(err).__name__}: {err})",)


def _locate(path: Path) -> _Source:
    if not path.exists():
        raise BagError(f"bag {path} does not exist")
    folder = path if path.is_dir() else path.parent
    counts, listed, problems = _metadata_counts(folder)
    if path.is_file():
        return _Source(path, counts if path.name in listed else None, problems)
    names = [n for n in listed if (folder / n).is_file()] or sorted(p.name for p in folder.glob("*.mcap"))
    if not names:
        raise BagError(f"bag {path} holds no .mcap file")
    if len(names) > 1:
        raise BagError(f"bag {path} is split into {names}; split bags are not supported")
    return _Source(folder / names[0], counts, problems)


# =========================================================================== raw messages
@dataclass
class _RawBag:
    """Raw CDR messages of the wanted topics."""

    msgtypes: dict[str, str] = field(default_factory=dict)
    data: dict[str, list[bytes | memoryview]] = field(default_factory=dict)
    typestore: Typestore | None = None


def _read_indexed(source: _Source, wanted: Callable[[str], bool]) -> tuple[_RawBag, dict[str, int]]:
    """Read through rosbags (the MCAP index). Returns the messages and the summary's counts."""
    target = source.mcap_path.parent if source.metadata_counts is not None else source.mcap_path
    raw = _RawBag()
    with AnyReader([target], default_typestore=project_typestore()) as reader:
        connections = [c for c in reader.connections if wanted(c.topic)]
        for conn in connections:
            raw.msgtypes[conn.topic] = conn.msgtype
            raw.data[conn.topic] = []
        for conn, _, data in reader.messages(connections=connections) if connections else ():
            raw.data[conn.topic].append(data)
        raw.typestore = reader.typestore
    return raw, {c.topic: c.msgcount for c in connections}


# --------------------------------------------------------------------------- salvage scan
_MAGIC = b"\x89MCAP0\r\n"
_OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_STATISTICS = 0x02, 0x03, 0x04, 0x05, 0x06, 0x0B


class _Damaged(Exception):
    """The scan met a record it cannot read; the message says where and why."""


@dataclass
class _Scan:
    """State of a record-by-record MCAP scan."""

    wanted: Callable[[str], bool]
    schemas: dict[int, tuple[str, str, str]] = field(default_factory=dict)
    channels: dict[int, tuple[str, int]] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    messages: dict[str, list[bytes]] = field(default_factory=dict)
    statistics: dict[int, int] | None = None


def _string(view: memoryview, pos: int) -> tuple[str, int]:
    (size,) = struct.unpack_from("<I", view, pos)
    end = pos + 4 + size
    if end > len(view):
        raise _Damaged(f"string of {size} bytes at byte {pos} runs past its record")
    return bytes(view[pos + 4:end]).decode("utf-8", errors="replace"), end


def _on_schema(scan: _Scan, body: memoryview) -> None:
    (schema_id,) = struct.unpack_from("<H", body, 0)
    name, pos = _string(body, 2)
    encoding, pos = _string(body, pos)
    text, _ = _string(body, pos)
    scan.schemas[schema_id] = (name, encoding, text)


def _on_channel(scan: _Scan, body: memoryview) -> None:
    channel_id, schema_id = struct.unpack_from("<HH", body, 0)
    topic, _ = _string(body, 4)
    scan.channels[channel_id] = (topic, schema_id)


def _on_message(scan: _Scan, body: memoryview) -> None:
    (channel_id,) = struct.unpack_from("<H", body, 0)
    if len(body) < 22 or channel_id not in scan.channels:
        raise _Damaged(f"message record of {len(body)} bytes on unknown channel {channel_id}")
    topic = scan.channels[channel_id][0]
    scan.counts[topic] = scan.counts.get(topic, 0) + 1
    if scan.wanted(topic):
        scan.messages.setdefault(topic, []).append(bytes(body[22:]))


def _on_statistics(scan: _Scan, body: memoryview) -> None:
    (size,) = struct.unpack_from("<I", body, 42)
    entries = body[46:46 + size]
    scan.statistics = {cid: n for cid, n in struct.iter_unpack("<HQ", entries)} if size % 10 == 0 else None


def _on_chunk(scan: _Scan, body: memoryview, *, truncated: bool) -> None:
    _, _, raw_size, crc = struct.unpack_from("<QQQI", body, 0)
    compression, pos = _string(body, 28)
    (size,) = struct.unpack_from("<Q", body, pos)
    records = body[pos + 8:pos + 8 + size]
    if compression:
        raise _Damaged(f"chunk compression {compression!r} is not supported by the salvage scan")
    if truncated:
        try:
            _scan_records(scan, records, nested=True)
        except _Damaged:
            pass
        raise _Damaged("the file ends inside a chunk; the complete messages of that chunk were kept")
    if len(records) != raw_size or (crc and zlib.crc32(records) != crc):
        raise _Damaged("a chunk fails its size or CRC check")
    _scan_records(scan, records, nested=True)


_HANDLERS: dict[int, Callable[[_Scan, memoryview], None]] = {
    _OP_SCHEMA: _on_schema, _OP_CHANNEL: _on_channel, _OP_MESSAGE: _on_message, _OP_STATISTICS: _on_statistics,
}


def _scan_records(scan: _Scan, view: memoryview, *, nested: bool) -> bool:
    """Handle every record of ``view``; True when a footer and the closing magic end it.

    Raise ``_Damaged`` at the first record that cannot be read.
    """
    pos = 0
    while pos < len(view):
        if pos + 9 > len(view):
            raise _Damaged(f"the file ends inside a record header at byte {pos}")
        opcode, (length,) = view[pos], struct.unpack_from("<Q", view, pos + 1)
        body, pos = view[pos + 9:pos + 9 + length], pos + 9 + length
        try:
            if opcode == _OP_CHUNK and not nested:
                _on_chunk(scan, body, truncated=pos > len(view))
            elif pos > len(view):
                raise _Damaged(f"the file ends inside a record (opcode {opcode:#x})")
            elif opcode == _OP_FOOTER:
                if bytes(view[pos:]) != _MAGIC:
                    raise _Damaged("the closing MCAP magic after the footer is cut or wrong")
                return True
            elif opcode in _HANDLERS:
                _HANDLERS[opcode](scan, body)
        except struct.error as err:
            raise _Damaged(f"malformed record (opcode {opcode:#x}): {err}") from err
    return False


def _scan_file(source: _Source, wanted: Callable[[str], bool]) -> tuple[_Scan, str]:
    """Scan the MCAP file record by record; return what was read and the problem met ('' if none)."""
    try:
        data = source.mcap_path.read_bytes()
    except OSError as err:
        raise BagError(f"cannot read {source.mcap_path}: {err}") from err
    scan = _Scan(wanted)
    if not data.startswith(_MAGIC):
        whole = _MAGIC.startswith(data)
        return scan, "the file ends inside the MCAP magic" if whole else "not an MCAP file (bad magic)"
    try:
        ended = _scan_records(scan, memoryview(data)[len(_MAGIC):], nested=False)
    except _Damaged as err:
        return scan, str(err)
    return scan, "" if ended else "the file ends without an MCAP footer (truncated)"


def _scan_typestore(scan: _Scan) -> Typestore:
    """Typestore from the file's own ``ros2msg`` schemas, else the project's."""
    try:
        store = get_typestore(Stores.EMPTY)
        for name, encoding, text in scan.schemas.values():
            if encoding != "ros2msg":
                return project_typestore()
            store.register(get_types_from_msg(text, name))
        return store
    except Exception:  # noqa: BLE001 - a damaged schema falls back to the project's definitions
        return project_typestore()


def _read_scanned(source: _Source, wanted: Callable[[str], bool], index_error: str) -> tuple[_RawBag, BagIntegrity]:
    scan, problem = _scan_file(source, wanted)
    raw = _RawBag(typestore=_scan_typestore(scan))
    for topic, schema_id in scan.channels.values():
        if wanted(topic):
            raw.msgtypes[topic] = scan.schemas.get(schema_id, ("",))[0]
            raw.data[topic] = scan.messages.get(topic, [])
    expected, expected_source = source.metadata_counts, "metadata.yaml"
    if expected is None and scan.statistics is not None:
        expected = {scan.channels[c][0]: n for c, n in scan.statistics.items() if c in scan.channels}
        expected_source = "mcap summary"
    problems = (f"index unreadable ({index_error})", *((problem,) if problem else ()), *source.problems)
    found = {topic: scan.counts.get(topic, 0) for topic in raw.msgtypes}
    found.update({t: scan.counts.get(t, 0) for t in (expected or {}) if wanted(t)})
    integrity = BagIntegrity(False, "scan", found, expected, expected_source if expected else "unknown", problems)
    return raw, integrity


def _read_raw(source: _Source, wanted: Callable[[str], bool]) -> tuple[_RawBag, BagIntegrity]:
    try:
        raw, summary_counts = _read_indexed(source, wanted)
    except Exception as err:  # noqa: BLE001 - a damaged file may make rosbags raise anything; the scan decides
        return _read_scanned(source, wanted, f"{type(err).__name__}: {err}")
    expected = source.metadata_counts if source.metadata_counts is not None else summary_counts
    found = {topic: len(data) for topic, data in raw.data.items()}
    found.update({t: found.get(t, 0) for t in expected if wanted(t)})
    mismatch = tuple(f"{t}: {found[t]} of {expected.get(t, 0)} messages" for t in found if found[t] != expected.get(t, 0))
    source_name = "metadata.yaml" if source.metadata_counts is not None else "mcap summary"
    return raw, BagIntegrity(not mismatch, "index", found, expected, source_name, mismatch + source.problems)


# =========================================================================== decoding
#: Type each topic of the suite must have (by the last part of its name).
_TOPIC_TYPES = {
    "joint_states": "sensor_msgs/msg/JointState",
    "reference": "cnc_contour_interfaces/msg/Reference",
    "path": PATH_TYPE,
    "command": "cnc_contour_interfaces/msg/AxisCommand",
}


@dataclass(frozen=True)
class _Fields:
    """What to decode from one topic: per-axis fields (name -> required), scalars, strings."""

    names_field: str | None = None
    axis_fields: Mapping[str, bool] = field(default_factory=dict)
    scalars: tuple[str, ...] = ()
    strings: tuple[str, ...] = ()


def _blocks(raw: _RawBag, topic: str) -> list[ColumnBlock]:
    msgtype = raw.msgtypes[topic]
    if msgtype != _TOPIC_TYPES[topic.rsplit("/", 1)[-1]]:
        raise BagError(f"{topic} has type {msgtype!r}, expected {_TOPIC_TYPES[topic.rsplit('/', 1)[-1]]!r}")
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


def _columns(raw: _RawBag, topic: str, spec: _Fields, axes: tuple[str, ...]) -> dict[str, np.ndarray | str]:
    """Decode a topic sorted by header stamp: per-axis fields (N, n_axes), scalars (N,), strings joined by '|'."""
    count = len(raw.data[topic])
    out: dict[str, np.ndarray] = {"stamp_ns": np.zeros(count, np.int64)}
    out.update({name: np.full((count, len(axes)), np.nan) for name in spec.axis_fields})
    strings: dict[str, set[str]] = {name: set() for name in spec.strings}
    needed = {"header.stamp.sec", "header.stamp.nanosec", *spec.axis_fields, *spec.scalars}
    for block in _blocks(raw, topic):
        missing = sorted(needed - set(block.numbers) | set(spec.strings) - set(block.strings))
        if missing:
            raise BagError(f"{topic}: the recorded {raw.msgtypes[topic]} has no fields {missing}")
        sec = block.numbers["header.stamp.sec"].astype(np.int64)
        out["stamp_ns"][block.rows] = sec * 1_000_000_000 + block.numbers["header.stamp.nanosec"]
        _fill_axes(out, block, spec, axes, topic)
        for name in spec.scalars:
            out.setdefault(name, np.zeros(count, block.numbers[name].dtype))[block.rows] = block.numbers[name]
        for name in spec.strings:
            strings[name].add(str(block.strings[name]))
    order = np.argsort(out["stamp_ns"], kind="stable")
    return {**{k: v[order] for k, v in out.items()}, **{k: "|".join(sorted(v)) for k, v in strings.items()}}


def _joint_states(raw: _RawBag, topic: str, axes: tuple[str, ...]) -> JointStateSeries:
    if not raw.data.get(topic):
        raise BagError(f"bag has no {topic} messages; found {sorted(t for t in raw.data if raw.data[t])}")
    cols = _columns(raw, topic, _Fields("name", {"position": True, "velocity": False}), axes)
    return JointStateSeries(cols["stamp_ns"], cols["position"], cols["velocity"])  # type: ignore[arg-type]


_REFERENCE = _Fields("axis_names", {"position_m": True, "velocity_m_s": False, "acceleration_m_s2": False},
                     ("path_length_m", "segment_index", "feed_m_s", "done"))


def _reference(raw: _RawBag, topic: str, axes: tuple[str, ...]) -> ReferenceSeries | None:
    if not raw.data.get(topic):
        return None
    c = _columns(raw, topic, _REFERENCE, axes)
    return ReferenceSeries(c["stamp_ns"], c["position_m"], c["velocity_m_s"], c["acceleration_m_s2"],  # type: ignore[arg-type]
                           c["path_length_m"], c["segment_index"].astype(np.int64), c["feed_m_s"],  # type: ignore[union-attr]
                           c["done"].astype(bool))  # type: ignore[union-attr]


_COMMAND = _Fields(scalars=("command", "feedback", "feedforward", "compensation", "disturbance_estimate",
                            "saturated", "error_m"), strings=("law", "command_unit"))


def _commands(raw: _RawBag, names: TopicNames, axes: tuple[str, ...]) -> dict[str, CommandSeries]:
    series: dict[str, CommandSeries] = {}
    for topic in sorted(raw.data):
        axis = names.command_axis(topic)
        if axis is not None and raw.data[topic]:
            cols = _columns(raw, topic, _COMMAND, axes)
            cols["saturated"] = cols["saturated"].astype(bool)  # type: ignore[union-attr]
            series[axis] = CommandSeries(axis_name=axis, **cols)  # type: ignore[arg-type]
    return series


# --------------------------------------------------------------------------- path -> program
def _line(seg: object, clockwise: bool) -> LineSegment:
    return LineSegment(start_m=np.asarray(seg.start_m, float), end_m=np.asarray(seg.end_m, float),  # type: ignore[attr-defined]
                       feed_m_s=float(seg.feed_m_s))  # type: ignore[attr-defined]


def _arc(seg: object, clockwise: bool) -> ArcSegment:
    return ArcSegment(start_m=np.asarray(seg.start_m, float), end_m=np.asarray(seg.end_m, float),  # type: ignore[attr-defined]
                      center_m=np.asarray(seg.center_m, float), clockwise=clockwise,  # type: ignore[attr-defined]
                      plane=tuple(int(i) for i in seg.plane_axes), feed_m_s=float(seg.feed_m_s))  # type: ignore[attr-defined]


#: PathSegment.kind -> (builder, clockwise).
_SEGMENT_KINDS: dict[int, tuple[Callable[[object, bool], LineSegment | ArcSegment], bool]] = {
    0: (_line, False), 1: (_arc, True), 2: (_arc, False),
}


def program_from_path(message: object) -> Program:
    """Build the program geometry from a deserialised ``cnc_contour_interfaces/msg/Path``."""
    segments = []
    for index, seg in enumerate(message.segments):  # type: ignore[attr-defined]
        if seg.kind not in _SEGMENT_KINDS:
            raise BagError(f"path segment {index}: kind {seg.kind} is not one of {sorted(_SEGMENT_KINDS)}")
        build, clockwise = _SEGMENT_KINDS[seg.kind]
        segments.append(build(seg, clockwise))
    return Program(name=message.program_name, axis_names=tuple(message.axis_names),  # type: ignore[attr-defined]
                   segments=segments)


def _program(raw: _RawBag, topic: str) -> Program:
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
    except Exception as err:  # noqa: BLE001 - a corrupt message may break the deserialiser anyhow
        raise BagError(f"{topic}: cannot decode the recorded program ({type(err).__name__}: {err})") from err


# =========================================================================== reading
def read_bag(path: str | Path, *, namespace: str = "/cnc", commands: bool = True) -> RecordedRun:
    """Read a recorded run.

    Parameters
    ----------
    path
        Bag folder (or its ``.mcap`` file).
    namespace
        Namespace of the suite's topics.
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
    names = TopicNames(namespace)
    source = _locate(Path(path))
    raw, integrity = _read_raw(source, lambda topic: names.wanted(topic, commands))
    try:
        program = _program(raw, names.topic("path"))
        axes = tuple(program.axis_names)
        return RecordedRun(
            name=source.mcap_path.parent.name if Path(path).is_dir() else source.mcap_path.stem,
            source=Path(path), program=program,
            joint_states=_joint_states(raw, names.topic("joint_states"), axes),
            reference=_reference(raw, names.topic("reference"), axes),
            commands=_commands(raw, names, axes) if commands else {}, integrity=integrity)
    except BagError as err:
        raise BagError(f"{path}: {err}" + ("" if integrity.complete else f" [{integrity.describe()}]")) from err
