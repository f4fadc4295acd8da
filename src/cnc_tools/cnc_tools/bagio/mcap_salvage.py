"""Salvage scan of a damaged MCAP file: read record by record, keep every intact message of the readable prefix.

Used when ``rosbags`` cannot read a file through its index (a truncated or
corrupt file). The scan follows the MCAP record layout (opcode u8, length u64,
body), enters uncompressed chunks (checking their size and CRC), and stops at
the first record it cannot read, saying why. No rclpy, no message types.
"""
from __future__ import annotations

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
_OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_STATISTICS = 0x02, 0x03, 0x04, 0x05, 0x06, 0x0B
#: Bytes of a Message record before its data: channel id u16, sequence u32, log time u64, publish time u64.
_MESSAGE_HEADER = 22

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
    """

    wanted: Callable[[str], bool]
    sink: MessageSink
    schemas: dict[int, tuple[str, str, str]] = field(default_factory=dict)
    channels: dict[int, tuple[str, int]] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    statistics: dict[int, int] | None = None

    def topic_types(self) -> dict[str, str]:
        """``{topic: type name}`` of the wanted channels seen."""
        return {topic: self.schemas.get(schema_id, ("",))[0]
                for topic, schema_id in self.channels.values() if self.wanted(topic)}

    def statistics_counts(self) -> dict[str, int] | None:
        """Messages per topic according to the file's summary, or ``None`` when it was not reached."""
        if self.statistics is None:
            return None
        return {self.channels[c][0]: n for c, n in self.statistics.items() if c in self.channels}


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
    if scan.wanted(topic):
        (log_time_ns,) = struct.unpack_from("<Q", body, 6)
        scan.sink(topic, log_time_ns, bytes(body[_MESSAGE_HEADER:]))


def _on_statistics(scan: SalvageScan, body: memoryview) -> None:
    (size,) = struct.unpack_from("<I", body, 42)
    entries = body[46:46 + size]
    scan.statistics = dict(struct.iter_unpack("<HQ", entries)) if size % 10 == 0 else None


def _on_chunk(scan: SalvageScan, body: memoryview, *, truncated: bool) -> None:
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


_HANDLERS: dict[int, Callable[[SalvageScan, memoryview], None]] = {
    _OP_SCHEMA: _on_schema, _OP_CHANNEL: _on_channel, _OP_MESSAGE: _on_message, _OP_STATISTICS: _on_statistics,
}


def _scan_records(scan: SalvageScan, view: memoryview, *, nested: bool) -> bool:
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
                if bytes(view[pos:]) != MAGIC:
                    raise _Damaged("the closing MCAP magic after the footer is cut or wrong")
                return True
            elif opcode in _HANDLERS:
                _HANDLERS[opcode](scan, body)
        except struct.error as err:
            raise _Damaged(f"malformed record (opcode {opcode:#x}): {err}") from err
    return False


def scan_mcap(mcap_path: Path, wanted: Callable[[str], bool], sink: MessageSink) -> tuple[SalvageScan, str]:
    """Scan an MCAP file record by record.

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
        What was found, and the problem met ('' when the file is intact to its closing magic).

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
    if not data.startswith(MAGIC):
        whole = MAGIC.startswith(data)
        return scan, "the file ends inside the MCAP magic" if whole else "not an MCAP file (bad magic)"
    try:
        ended = _scan_records(scan, memoryview(data)[len(MAGIC):], nested=False)
    except _Damaged as err:
        return scan, str(err)
    return scan, "" if ended else "the file ends without an MCAP footer (truncated)"


#: Bytes of the Footer record (opcode, length, summary start u64, summary offset start u64, summary CRC u32).
_FOOTER_BYTES = 1 + 8 + 20
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
    """Typestore from the file's own ``ros2msg`` schemas, else the project's."""
    try:
        store = get_typestore(Stores.EMPTY)
        for name, encoding, text in scan.schemas.values():
            if encoding != "ros2msg":
                return project_typestore()
            store.register(get_types_from_msg(text, name))
        return store
    except Exception:
        return project_typestore()
