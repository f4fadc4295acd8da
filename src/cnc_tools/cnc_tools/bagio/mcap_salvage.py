"""Salvage scan of a damaged MCAP file: read record by record, keep every intact message, skip damaged chunks.

Used when ``rosbags`` cannot read a file through its index (a truncated or
corrupt file). The scan follows the MCAP record layout (opcode u8, length u64,
body) and enters uncompressed chunks, checking each one's lengths and CRC. A
chunk that fails them (or any record that cannot be read) is skipped: the scan
resynchronises on the next chunk whose lengths agree and whose CRC matches, so
one flipped bit loses at most the chunk it lies in. Each damaged stretch is
noted in words with the messages its chunk held per topic (from the Message
Index records that follow a chunk). The channels and the per-topic counts come
from the summary too when its CRC matches, so messages after a damaged first
chunk (which holds the Schema and Channel records) are still named. A file
that ends inside a chunk keeps that chunk's complete messages. No rclpy, no
message types.
"""
from __future__ import annotations

import functools
import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from cnc_contour_control.core.errors import BagError
from cnc_tools.bagio.typestore import project_typestore

MAGIC = b"\x89MCAP0\r\n"
_OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_MESSAGE_INDEX = 0x02, 0x03, 0x04, 0x05, 0x06, 0x07
_OP_CHUNK_INDEX, _OP_STATISTICS, _OP_LAST = 0x08, 0x0B, 0x0F
#: Bytes of a Message record before its data: channel id u16, sequence u32, log time u64, publish time u64.
_MESSAGE_HEADER = 22
#: Bytes of a Chunk record's body besides its compression name and records: times, sizes, CRC, two lengths.
_CHUNK_FIXED = 8 + 8 + 8 + 4 + 4 + 8
#: Longest compression name a chunk may carry; a longer one marks noise, not a chunk.
_MAX_COMPRESSION_BYTES = 16
_U64 = struct.Struct("<Q")

#: Receives each wanted message: topic, log time (ns), CDR bytes.
MessageSink = Callable[[str, int, bytes], None]


class _Damaged(Exception):
    """The scan met a record it cannot read; the message says where and why."""


@dataclass
class SalvageScan:
    """What a record-by-record scan found.

    Attributes
    ----------
    wanted
        Topics whose messages go to ``sink``; the others are only counted.
    sink
        Called with (topic, log time ns, CDR bytes) for each wanted message, in file order.
    schemas
        ``{schema id: (type name, encoding, text)}``.
    channels
        ``{channel id: (topic, schema id)}``.
    counts
        Intact messages per topic (wanted or not).
    statistics
        ``{channel id: message count}`` from the file's Statistics record, if it was reached.
    damage
        One line per damaged stretch skipped: where, why, and the messages lost with it per topic.
    summary_damaged
        The summary fails its CRC: its statistics are not used.
    chunk_indexes
        ``{chunk offset: {channel id: message index offset}}`` from a summary whose CRC matches.
    wanted_topics
        ``wanted`` of each topic met so far.
    """

    wanted: Callable[[str], bool]
    sink: MessageSink
    schemas: dict[int, tuple[str, str, str]] = field(default_factory=dict)
    channels: dict[int, tuple[str, int]] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    statistics: dict[int, int] | None = None
    damage: list[str] = field(default_factory=list)
    summary_damaged: bool = False
    chunk_indexes: dict[int, dict[int, int]] = field(default_factory=dict)
    wanted_topics: dict[str, bool] = field(default_factory=dict)

    def topic_types(self) -> dict[str, str]:
        """``{topic: type name}`` of the wanted channels seen."""
        return {topic: self.schemas.get(schema_id, ("",))[0]
                for topic, schema_id in self.channels.values() if self.wanted(topic)}

    def statistics_counts(self) -> dict[str, int] | None:
        """Messages per topic according to the file's summary, or ``None`` when it was not reached."""
        if self.statistics is None:
            return None
        return {self.channels[c][0]: n for c, n in self.statistics.items() if c in self.channels}

    def topic(self, channel_id: int) -> str:
        """The topic of a channel, or ``channel N`` when its Channel record was lost."""
        return self.channels[channel_id][0] if channel_id in self.channels else f"channel {channel_id}"


def _string(view: memoryview, pos: int) -> tuple[str, int]:
    (size,) = struct.unpack_from("<I", view, pos)
    end = pos + 4 + size
    if end > len(view):
        raise _Damaged(f"string of {size} bytes at byte {pos} runs past its record")
    return bytes(view[pos + 4:end]).decode("utf-8", errors="replace"), end


def _on_schema(scan: SalvageScan, body: memoryview) -> None:
    (schema_id,) = struct.unpack_from("<H", body, 0)
    name, pos = _string(body, 2)
    encoding, pos = _string(body, pos)
    text, _ = _string(body, pos)
    scan.schemas[schema_id] = (name, encoding, text)


def _on_channel(scan: SalvageScan, body: memoryview) -> None:
    channel_id, schema_id = struct.unpack_from("<HH", body, 0)
    topic, _ = _string(body, 4)
    scan.channels[channel_id] = (topic, schema_id)


def _on_message(scan: SalvageScan, body: memoryview) -> None:
    (channel_id,) = struct.unpack_from("<H", body, 0)
    if len(body) < _MESSAGE_HEADER or channel_id not in scan.channels:
        raise _Damaged(f"message record of {len(body)} bytes on unknown channel {channel_id}")
    topic = scan.channels[channel_id][0]
    scan.counts[topic] = scan.counts.get(topic, 0) + 1
    wanted = scan.wanted_topics.get(topic)
    if wanted is None:                                   # ``wanted`` once per topic, not per message
        wanted = scan.wanted_topics[topic] = scan.wanted(topic)
    if wanted:
        (log_time_ns,) = struct.unpack_from("<Q", body, 6)
        scan.sink(topic, log_time_ns, bytes(body[_MESSAGE_HEADER:]))


def _on_statistics(scan: SalvageScan, body: memoryview) -> None:
    if scan.summary_damaged:
        return
    (size,) = struct.unpack_from("<I", body, 42)
    entries = body[46:46 + size]
    scan.statistics = dict(struct.iter_unpack("<HQ", entries)) if size % 10 == 0 else None


def _on_chunk_index(scan: SalvageScan, body: memoryview) -> None:
    (chunk_offset,) = struct.unpack_from("<Q", body, 16)
    (size,) = struct.unpack_from("<I", body, 32)
    if size % 10 == 0 and 36 + size <= len(body):
        scan.chunk_indexes[chunk_offset] = dict(struct.iter_unpack("<HQ", body[36:36 + size]))


_HANDLERS: dict[int, Callable[[SalvageScan, memoryview], None]] = {
    _OP_SCHEMA: _on_schema, _OP_CHANNEL: _on_channel, _OP_MESSAGE: _on_message, _OP_STATISTICS: _on_statistics,
}


def _scan_records(scan: SalvageScan, view: memoryview, handlers: dict[int, Callable[[SalvageScan, memoryview], None]]
                  = _HANDLERS) -> None:
    """Handle every record of a chunk's records (or of the summary); ``_Damaged`` at the first unreadable one."""
    pos = 0
    while pos < len(view):
        if pos + 9 > len(view):
            raise _Damaged(f"a record header is cut at byte {pos} of a chunk")
        opcode, (length,) = view[pos], _U64.unpack_from(view, pos + 1)
        body, pos = view[pos + 9:pos + 9 + length], pos + 9 + length
        if pos > len(view):
            raise _Damaged(f"a record (opcode {opcode:#x}) runs past the end of its chunk")
        handler = handlers.get(opcode)
        try:
            if handler is not None:
                handler(scan, body)
        except struct.error as err:
            raise _Damaged(f"malformed record (opcode {opcode:#x}): {err}") from err


# =========================================================================== chunks and resynchronisation
def _chunk_layout(view: memoryview, pos: int) -> tuple[int, int, int]:
    """(records start, records end, CRC) of the chunk record at ``pos``, if its lengths agree; else ``_Damaged``."""
    try:
        (length,) = _U64.unpack_from(view, pos + 1)
        _, _, raw_size, crc, name_size = struct.unpack_from("<QQQII", view, pos + 9)
        if name_size > _MAX_COMPRESSION_BYTES:
            raise _Damaged(f"chunk at byte {pos}: a compression name of {name_size} bytes")
        compression = bytes(view[pos + 41:pos + 41 + name_size])
        (size,) = _U64.unpack_from(view, pos + 41 + name_size)
    except struct.error as err:
        raise _Damaged(f"the file ends inside the chunk header at byte {pos}") from err
    if length != _CHUNK_FIXED + name_size + size:
        raise _Damaged(f"chunk at byte {pos}: record length {length} disagrees with its records' {size} bytes")
    if compression:
        raise _Damaged(f"chunk compression {compression!r} is not supported by the salvage scan")
    if size != raw_size:
        raise _Damaged(f"chunk at byte {pos}: records of {size} bytes, uncompressed size {raw_size}")
    start = pos + 49 + name_size
    return start, start + size, crc


def _walks_exactly(records: memoryview) -> bool:
    """Records of known opcodes that fill ``records`` exactly (how a chunk without a CRC is vouched for)."""
    pos = 0
    while pos + 9 <= len(records) and 0x01 <= records[pos] <= _OP_LAST:
        pos += 9 + _U64.unpack_from(records, pos + 1)[0]
    return pos == len(records)


def _next_chunk(data: bytes, start: int) -> int | None:
    """Offset of the first chunk at or after ``start`` whose lengths agree and whose CRC matches; None if none."""
    view = memoryview(data)
    pos = data.find(_OP_CHUNK, start)
    while pos >= 0:
        try:
            begin, end, crc = _chunk_layout(view, pos)
            records = view[begin:end]
            if end <= len(data) and (zlib.crc32(records) == crc if crc else _walks_exactly(records)):
                return pos
        except _Damaged:
            pass
        pos = data.find(_OP_CHUNK, pos + 1)
    return None


def _on_chunk(scan: SalvageScan, view: memoryview, pos: int) -> int:
    """Read the chunk at ``pos`` (its complete messages only, if the file ends inside it); its end offset."""
    begin, end, crc = _chunk_layout(view, pos)
    if end > len(view):
        try:
            _scan_records(scan, view[begin:])
        except _Damaged:
            pass
        raise _Damaged("the file ends inside a chunk; the complete messages of that chunk were kept")
    if crc and zlib.crc32(view[begin:end]) != crc:
        raise _Damaged(f"chunk at byte {pos} fails its CRC")
    _scan_records(scan, view[begin:end])
    return end


def _lost_in(scan: SalvageScan, data: bytes, start: int, stop: int) -> str:
    """The messages per topic of the summary's chunks that begin in ``[start, stop)``, in words."""
    if not scan.chunk_indexes:
        return "which messages it held is unknown (no intact summary)"
    lost: dict[str, int] = {}
    for offset, indexes in scan.chunk_indexes.items():
        if start <= offset < stop:
            for channel_id, at in indexes.items():
                size = struct.unpack_from("<I", data, at + 11)[0] if at + 15 <= len(data) else 0
                lost[scan.topic(channel_id)] = lost.get(scan.topic(channel_id), 0) + size // 16
    listed = ", ".join(f"{topic}: {n}" for topic, n in lost.items())
    return f"{sum(lost.values())} messages lost with it ({listed})" if lost else "no messages lost with it"


def _outside_chunks(scan: SalvageScan, opcode: int, body: memoryview) -> None:
    """A record outside every chunk (the summary's, in the files the suite writes): no chunk CRC vouches for it.

    Nothing but messages is taken from a file whose summary fails its CRC, and a
    schema or channel already read (from a checked chunk or summary) is kept.
    """
    if opcode != _OP_MESSAGE and scan.summary_damaged:
        return
    if opcode in (_OP_SCHEMA, _OP_CHANNEL):
        (record_id,) = struct.unpack_from("<H", body, 0)
        if record_id in (scan.schemas if opcode == _OP_SCHEMA else scan.channels):
            return
    _HANDLERS[opcode](scan, body)


def _top_record(scan: SalvageScan, view: memoryview, pos: int) -> int | None:
    """Handle the top-level record at ``pos``; the offset after it, or None at a footer followed by the magic."""
    if pos + 9 > len(view):
        raise _Damaged(f"the file ends inside a record header at byte {pos}")
    opcode, (length,) = view[pos], _U64.unpack_from(view, pos + 1)
    if not 0x01 <= opcode <= _OP_LAST:
        raise _Damaged(f"no record at byte {pos} (opcode {opcode:#x})")
    if opcode == _OP_CHUNK:
        return _on_chunk(scan, view, pos)
    end = pos + 9 + length
    if end > len(view):
        raise _Damaged(f"the file ends inside a record (opcode {opcode:#x}) at byte {pos}")
    if opcode == _OP_FOOTER:
        if bytes(view[end:]) != MAGIC:
            raise _Damaged("the closing MCAP magic after the footer is cut or wrong")
        return None
    if opcode in _HANDLERS:
        try:
            _outside_chunks(scan, opcode, view[pos + 9:end])
        except struct.error as err:
            raise _Damaged(f"malformed record (opcode {opcode:#x}) at byte {pos}: {err}") from err
    return end


def _scan_file(scan: SalvageScan, data: bytes) -> bool:
    """Handle every top-level record, skipping damage; True when a footer and the closing magic end the file.

    After damage the scan goes on at the first vouched-for chunk after the last
    chunk it read (a damaged length may have jumped past good chunks).
    ``_Damaged`` when no intact chunk follows the damage.
    """
    view, pos = memoryview(data), len(MAGIC)
    resume_from = pos                                     # the end of the last chunk read
    searched_past = pos                                   # past the last chunk resumed at (no loop on it)
    while pos < len(data):
        try:
            end = _top_record(scan, view, pos)
        except _Damaged as err:
            after = _next_chunk(data, max(resume_from, searched_past))
            if after is None:
                raise
            scan.damage.append(f"bytes {resume_from}-{after} damaged ({err}): skipped to the next intact chunk; "
                               + _lost_in(scan, data, resume_from, after))
            pos, searched_past = after, after + 1
            continue
        if end is None:
            return True
        if view[pos] == _OP_CHUNK:
            resume_from = end
        pos = end
    return False


#: Bytes of the Footer record (opcode, length, summary start u64, summary offset start u64, summary CRC u32).
_FOOTER_BYTES = 1 + 8 + 20


def _read_summary(scan: SalvageScan, data: bytes) -> None:
    """Channels, schemas, statistics and chunk indexes of the summary, when its CRC matches (or is not set)."""
    footer = len(data) - len(MAGIC) - _FOOTER_BYTES
    if footer < len(MAGIC) or data[footer] != _OP_FOOTER or not data.endswith(MAGIC):
        return
    summary_start, _, summary_crc = struct.unpack_from("<QQI", data, footer + 9)
    if not len(MAGIC) <= summary_start < footer:
        return
    if summary_crc and zlib.crc32(memoryview(data)[summary_start:footer + 9 + 16]) != summary_crc:
        scan.summary_damaged = True
        return
    try:
        _scan_records(scan, memoryview(data)[summary_start:footer], {**_HANDLERS, _OP_CHUNK_INDEX: _on_chunk_index})
    except _Damaged:
        scan.summary_damaged = True


def scan_mcap(mcap_path: Path, wanted: Callable[[str], bool], sink: MessageSink) -> tuple[SalvageScan, str]:
    """Scan an MCAP file record by record, skipping damaged chunks.

    Parameters
    ----------
    mcap_path
        The ``.mcap`` file.
    wanted
        Topics whose messages are handed to ``sink``.
    sink
        Receives (topic, log time ns, CDR bytes) of each intact wanted message, in file order.

    Returns
    -------
    tuple
        What was found (``damage`` lists each damaged stretch skipped), and the
        problem that ended the scan ('' when it reached the closing magic).

    Raises
    ------
    BagError
        The file cannot be read at all.
    """
    try:
        data = mcap_path.read_bytes()
    except OSError as err:
        raise BagError(f"cannot read {mcap_path}: {err}") from err
    scan = SalvageScan(wanted, sink)
    if len(data) < len(MAGIC) or sum(a != b for a, b in zip(data, MAGIC, strict=False)) > 1:
        whole = MAGIC.startswith(data)
        return scan, "the file ends inside the MCAP magic" if whole else "not an MCAP file (bad magic)"
    if not data.startswith(MAGIC):
        scan.damage.append("the opening MCAP magic is damaged (one byte)")
    _read_summary(scan, data)
    try:
        ended = _scan_file(scan, data)
    except _Damaged as err:
        return scan, str(err)
    return scan, "" if ended else "the file ends without an MCAP footer (truncated)"


#: Bytes of the DataEnd record (opcode, length, data section CRC u32).
_DATA_END_BYTES = 1 + 8 + 4
_OP_DATA_END = 0x0F


def crc_problem(data: bytes) -> str:
    """Check an MCAP file's data-section and summary CRCs; '' when they match or the file has none.

    The data-section CRC (DataEnd record) covers every byte before it: chunks,
    message indexes and metadata records alike, so one flipped byte anywhere in
    the data is found; the summary CRC (Footer) covers the summary and the
    footer's offsets. A CRC of 0 means "not computed" (rosbags' own writer).
    """
    footer = len(data) - len(MAGIC) - _FOOTER_BYTES
    if footer < len(MAGIC) or data[footer] != _OP_FOOTER or not data.endswith(MAGIC):
        return "the MCAP footer is missing or damaged"
    summary_start, _, summary_crc = struct.unpack_from("<QQI", data, footer + 9)
    summary_from = summary_start or footer
    data_end = summary_from - _DATA_END_BYTES
    if not len(MAGIC) <= data_end < footer or data[data_end] != _OP_DATA_END:
        return f"no DataEnd record before the summary (summary start {summary_start})"
    (data_crc,) = struct.unpack_from("<I", data, data_end + 9)
    if data_crc and zlib.crc32(memoryview(data)[:data_end]) != data_crc:  # a view: no copy of the file
        return "the data section fails its CRC (a damaged byte among the recorded data)"
    if summary_crc and zlib.crc32(data[summary_from:footer + 9 + 16]) != summary_crc:
        return "the summary section fails its CRC"
    return ""


def scan_typestore(scan: SalvageScan) -> Typestore:
    """Typestore from the file's own ``ros2msg`` schemas, else the project's (one per set of schemas)."""
    return _schemas_typestore(tuple(sorted(scan.schemas.values())))


@functools.lru_cache(maxsize=8)
def _schemas_typestore(schemas: tuple[tuple[str, str, str], ...]) -> Typestore:
    """A typestore of these (name, encoding, text) schemas; built once (60 ms a time for a run's six types)."""
    try:
        store = get_typestore(Stores.EMPTY)
        for name, encoding, text in schemas:
            if encoding != "ros2msg":
                return project_typestore()
            store.register(get_types_from_msg(text, name))
        return store
    except Exception:
        return project_typestore()
