"""A small MCAP writer whose per-message step is one struct pack: the recorder's hot path.

It writes exactly the records :class:`cnc_tools.bagio.mcap_storage.CheckedMcapStorage`
needs, laid out as ``mcap.writer.Writer(chunk_size=..., compression=NONE,
enable_crcs=True, enable_data_crcs=True)`` lays them out, byte for byte (the
tests compare the two files):

- magic, Header (profile, library);
- Schema and Channel records go into the chunk being filled (a chunk holding
  only them is never closed: they wait for the next message);
- Message records (opcode 0x05: channel u16, sequence u32, log and publish time
  u64 [ns], data) into an uncompressed chunk; the chunk closes once its records
  exceed ``chunk_size_bytes`` or on :meth:`McapWriter.flush`; a Chunk record
  (times, size, CRC-32 of its records, ``""`` compression) is followed by one
  Message Index per channel (in the order the chunk first saw it);
- a Metadata record goes to the file at once (an open chunk stays open);
- Data End with the CRC-32 of everything before it; the summary: schemas,
  channels, statistics, chunk indexes, an (empty) attachment-index group,
  metadata indexes, summary offsets; Footer with the summary CRC; magic.

Per message: ``bytearray += pack(header)``, ``+= data``, two list appends for
the message index; no per-field writes, no record objects.
"""
from __future__ import annotations

import struct
import zlib
from collections.abc import Mapping
from typing import BinaryIO

#: The MCAP magic bytes (version 0) that open and close a file.
MAGIC = b"\x89MCAP0\r\n"

_OP_HEADER, _OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE = 0x01, 0x02, 0x03, 0x04, 0x05
_OP_CHUNK, _OP_MESSAGE_INDEX, _OP_CHUNK_INDEX, _OP_ATTACHMENT_INDEX = 0x06, 0x07, 0x08, 0x0A
_OP_STATISTICS, _OP_METADATA, _OP_METADATA_INDEX, _OP_SUMMARY_OFFSET, _OP_DATA_END = 0x0B, 0x0C, 0x0D, 0x0E, 0x0F

#: Opcode, record length, channel, sequence, log time, publish time: the fixed part of a Message record.
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")
_MESSAGE_FIXED_BYTES = _MESSAGE_HEAD.size - 9
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")


def _string(value: str) -> bytes:
    """A length-prefixed UTF-8 string."""
    raw = value.encode()
    return _U32.pack(len(raw)) + raw


def _string_map(items: Mapping[str, str]) -> bytes:
    """A length-prefixed map of length-prefixed strings, in the mapping's order."""
    body = b"".join(_string(k) + _string(v) for k, v in items.items())
    return _U32.pack(len(body)) + body


def _record(opcode: int, body: bytes) -> bytes:
    """One record: opcode u8, body length u64, body."""
    return struct.pack("<BQ", opcode, len(body)) + body


class McapWriter:
    """Write an MCAP file in uncompressed, CRC-checked chunks (see the module docstring).

    Parameters
    ----------
    stream
        Binary file open for writing, positioned at its start; not closed here.
    chunk_size_bytes
        A chunk closes once its records exceed this size [bytes].
    max_share
        If given, the chunk size grows with the file: a chunk closes past ``max_share`` of the bytes written
        before it (never below ``chunk_size_bytes``, never above ``max_chunk_bytes``), so one damaged chunk is
        at most that share of a run of any length while a long run is read in few chunks. None: a fixed size,
        as ``mcap.writer.Writer`` writes (byte-identical to it).
    max_chunk_bytes
        The largest chunk size ``max_share`` may grow to [bytes].
    """

    def __init__(self, stream: BinaryIO, chunk_size_bytes: int, max_share: float | None = None,
                 max_chunk_bytes: int = 1 << 20) -> None:
        self._stream = stream
        self._chunk_size_bytes = self._min_chunk_bytes = chunk_size_bytes
        self._max_share = max_share
        self._max_chunk_bytes = max(max_chunk_bytes, chunk_size_bytes)
        self._offset = 0                                   # bytes written to the file
        self._data_crc = 0
        self._schemas: list[bytes] = []
        self._channels: list[bytes] = []
        self._chunk = bytearray()
        self._index: dict[int, list[int]] = {}             # channel -> [log_time, offset, ...] of this chunk
        self._chunk_start_ns = 0
        self._chunk_end_ns = 0
        self._counts: dict[int, int] = {}                  # channel -> messages of closed chunks, first seen first
        self._start_ns = 0
        self._end_ns = 0
        self._chunk_indexes: list[bytes] = []
        self._metadata_indexes: list[bytes] = []
        self._metadata_count = 0

    # ------------------------------------------------------------------ data section
    def _emit(self, data: bytes | bytearray) -> None:
        """Write ``data`` to the data section (file and data CRC)."""
        self._stream.write(data)
        self._data_crc = zlib.crc32(data, self._data_crc)
        self._offset += len(data)

    def start(self, profile: str, library: str) -> None:
        """Write the magic and the Header record."""
        self._emit(MAGIC)
        self._emit(_record(_OP_HEADER, _string(profile) + _string(library)))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        """Add a Schema record; returns its id (1, 2, ...)."""
        schema_id = len(self._schemas) + 1
        record = _record(_OP_SCHEMA, _U16.pack(schema_id) + _string(name) + _string(encoding)
                         + _U32.pack(len(data)) + data)
        self._schemas.append(record)
        self._chunk += record
        self._close_if_full()
        return schema_id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: Mapping[str, str]) -> int:
        """Add a Channel record; returns its id (1, 2, ...)."""
        channel_id = len(self._channels) + 1
        record = _record(_OP_CHANNEL, _U16.pack(channel_id) + _U16.pack(schema_id) + _string(topic)
                         + _string(message_encoding) + _string_map(metadata))
        self._channels.append(record)
        self._chunk += record
        self._close_if_full()
        return channel_id

    def add_message(self, channel_id: int, log_time_ns: int, data: bytes | bytearray | memoryview,
                    publish_time_ns: int) -> None:
        """Append one Message record (sequence 0) to the chunk; close the chunk past its size."""
        chunk = self._chunk
        index = self._index.get(channel_id)
        if index is None:
            if not self._index:                            # the chunk's first message
                self._chunk_start_ns = self._chunk_end_ns = log_time_ns
            index = self._index[channel_id] = []
        index += (log_time_ns, len(chunk))
        if log_time_ns < self._chunk_start_ns:
            self._chunk_start_ns = log_time_ns
        elif log_time_ns > self._chunk_end_ns:
            self._chunk_end_ns = log_time_ns
        chunk += _MESSAGE_HEAD.pack(_OP_MESSAGE, _MESSAGE_FIXED_BYTES + len(data), channel_id, 0,
                                    log_time_ns, publish_time_ns)
        chunk += data
        if len(chunk) > self._chunk_size_bytes:
            self._close_chunk()

    def _close_if_full(self) -> None:
        """Close the chunk once its records exceed the chunk size (only if it holds a message)."""
        if len(self._chunk) > self._chunk_size_bytes:
            self._close_chunk()

    def _close_chunk(self) -> None:
        """Write the chunk in progress (if it holds a message) and its message indexes; note its index."""
        if not self._index:
            return
        chunk, self._chunk = self._chunk, bytearray()
        start_ns, end_ns = self._chunk_start_ns, self._chunk_end_ns
        self._note_times(start_ns, end_ns)
        chunk_start = self._offset
        head = struct.pack("<BQQQQI", _OP_CHUNK, 8 + 8 + 8 + 4 + 4 + 8 + len(chunk), start_ns, end_ns,
                           len(chunk), zlib.crc32(chunk)) + _string("") + _U64.pack(len(chunk))
        self._emit(head)
        self._emit(chunk)
        if self._max_share is not None:
            self._chunk_size_bytes = min(self._max_chunk_bytes,
                                         max(self._min_chunk_bytes, int(self._max_share * chunk_start)))
        index_start = self._offset
        offsets, indexes = bytearray(), bytearray()
        for channel_id, entries in self._index.items():
            offsets += struct.pack("<HQ", channel_id, index_start + len(indexes))
            indexes += struct.pack(f"<BQHI{len(entries)}Q", _OP_MESSAGE_INDEX, 6 + 8 * len(entries), channel_id,
                                   8 * len(entries), *entries)
            self._counts[channel_id] = self._counts.get(channel_id, 0) + len(entries) // 2
        self._emit(indexes)
        self._index = {}
        body = (struct.pack("<QQQQ", start_ns, end_ns, chunk_start, len(head) + len(chunk))
                + _U32.pack(len(offsets)) + offsets + _U64.pack(len(indexes)) + _string("")
                + _U64.pack(len(chunk)) + _U64.pack(len(chunk)))
        self._chunk_indexes.append(_record(_OP_CHUNK_INDEX, body))

    def _note_times(self, start_ns: int, end_ns: int) -> None:
        """Widen the file's message time range to a closed chunk's."""
        if not self._chunk_indexes:
            self._start_ns = start_ns
        self._start_ns = min(self._start_ns, start_ns)
        self._end_ns = max(self._end_ns, end_ns)

    def flush(self) -> None:
        """Close the chunk in progress (if it holds a message) and flush the stream."""
        self._close_chunk()
        self._stream.flush()

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write a Metadata record now (an open chunk stays open) and note its index."""
        record = _record(_OP_METADATA, _string(name) + _string_map(data))
        self._metadata_indexes.append(_record(_OP_METADATA_INDEX, _U64.pack(self._offset)
                                              + _U64.pack(len(record)) + _string(name)))
        self._metadata_count += 1
        self._emit(record)

    # ------------------------------------------------------------------ summary
    def finish(self) -> None:
        """Close the last chunk; write Data End, the summary, the Footer and the closing magic."""
        self._close_chunk()
        self._emit(_record(_OP_DATA_END, _U32.pack(self._data_crc)))
        summary_start = self._offset
        summary, offsets = bytearray(), bytearray()
        for opcode, records in self._summary_groups():
            group_start = len(summary)
            for record in records:
                summary += record
            offsets += _record(_OP_SUMMARY_OFFSET, struct.pack("<BQQ", opcode, summary_start + group_start,
                                                                len(summary) - group_start))
        offsets_start = summary_start + len(summary)
        summary += offsets
        footer_head = struct.pack("<BQQQ", _OP_FOOTER, 8 + 8 + 4, summary_start, offsets_start)
        summary_crc = zlib.crc32(footer_head, zlib.crc32(summary))
        self._stream.write(summary)
        self._stream.write(footer_head + _U32.pack(summary_crc) + MAGIC)
        self._offset += len(summary) + len(footer_head) + 4 + len(MAGIC)

    def _summary_groups(self) -> list[tuple[int, list[bytes]]]:
        """The summary's record groups in file order, by opcode."""
        counts = b"".join(struct.pack("<HQ", channel_id, n) for channel_id, n in self._counts.items())
        statistics = _record(_OP_STATISTICS, struct.pack(
            "<QHIIIIQQ", sum(self._counts.values()), len(self._schemas), len(self._channels), 0,
            self._metadata_count, len(self._chunk_indexes), self._start_ns, self._end_ns)
            + _U32.pack(len(counts)) + counts)
        return [(_OP_SCHEMA, self._schemas), (_OP_CHANNEL, self._channels), (_OP_STATISTICS, [statistics]),
                (_OP_CHUNK_INDEX, self._chunk_indexes), (_OP_ATTACHMENT_INDEX, []),
                (_OP_METADATA_INDEX, self._metadata_indexes)]
