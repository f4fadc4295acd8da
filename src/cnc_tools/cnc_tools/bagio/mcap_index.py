"""Where the messages of chosen topics lie in an MCAP file, found through its indexes with numpy.

The summary's Chunk Index records and each chunk's Message Index records give,
per channel, the offset and log time of every message; numpy gathers the
record headers at those offsets and checks them all at once (a Message record,
of that channel, at that log time, inside its chunk). The messages come back in
the order ``rosbags`` yields them (log time, then position in the file) without
a Python step per message.

Only a file this module can vouch for is read so: uncompressed chunks whose
CRCs match, a Statistics record whose per-channel counts the message indexes
match, one channel per topic, every index entry a distinct, well-formed
Message record. Anything else gives ``None`` and the caller reads through
``rosbags``. No rclpy, no message types.
"""
from __future__ import annotations

import struct
import zlib
from collections.abc import Collection
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

MAGIC = b"\x89MCAP0\r\n"
_OP_FOOTER, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK = 0x02, 0x04, 0x05, 0x06
_OP_MESSAGE_INDEX, _OP_CHUNK_INDEX, _OP_STATISTICS = 0x07, 0x08, 0x0B
#: Footer record: opcode, length, summary start u64, summary offset start u64, summary CRC u32.
_FOOTER_BYTES = 1 + 8 + 20
#: Message record before its data: opcode u8, length u64, channel u16, sequence u32, log and publish time u64.
_MESSAGE_HEAD_BYTES = 1 + 8 + 22
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")


class _Unsupported(Exception):
    """The file is not one this module vouches for; read it through rosbags."""


@dataclass
class _Summary:
    """Channels, chunk indexes and statistics of the summary section."""

    topics: dict[int, str] = field(default_factory=dict)
    #: (message start ns, message end ns, chunk offset, {channel: message index offset}, compression).
    chunks: list[tuple[int, int, int, dict[int, int], str]] = field(default_factory=list)
    counts: dict[int, int] | None = None


@dataclass(frozen=True)
class MessageLocations:
    """The messages of the wanted topics, in rosbags' order (log time, then file position).

    Attributes
    ----------
    topics
        ``{channel id: topic}`` of the wanted topics the file has.
    channel
        (N,) channel id of each message.
    log_time_ns
        (N,) log time of each message [ns].
    start, end
        (N,) byte range of each message's CDR data in the file.
    """

    topics: dict[int, str]
    channel: NDArray[np.int64]
    log_time_ns: NDArray[np.int64]
    start: NDArray[np.int64]
    end: NDArray[np.int64]


def _string(data: bytes, pos: int) -> tuple[str, int]:
    (size,) = _U32.unpack_from(data, pos)
    return data[pos + 4:pos + 4 + size].decode("utf-8", errors="replace"), pos + 4 + size


def _on_chunk_index(summary: _Summary, data: bytes, pos: int) -> None:
    start_ns, end_ns, chunk_offset, _ = struct.unpack_from("<QQQQ", data, pos)
    (size,) = _U32.unpack_from(data, pos + 32)
    entries = data[pos + 36:pos + 36 + size]
    if size % 10:
        raise _Unsupported("message index offsets of a chunk index")
    indexes = dict(struct.iter_unpack("<HQ", entries))
    compression, _ = _string(data, pos + 36 + size + 8)
    summary.chunks.append((start_ns, end_ns, chunk_offset, indexes, compression))


def _on_statistics(summary: _Summary, data: bytes, pos: int) -> None:
    (size,) = _U32.unpack_from(data, pos + 42)
    if size % 10:
        raise _Unsupported("channel message counts of the statistics")
    summary.counts = dict(struct.iter_unpack("<HQ", data[pos + 46:pos + 46 + size]))


def _read_summary(data: bytes) -> _Summary:
    footer = len(data) - len(MAGIC) - _FOOTER_BYTES
    if footer < len(MAGIC) or data[footer] != _OP_FOOTER or not data.endswith(MAGIC):
        raise _Unsupported("no footer")
    (pos,) = _U64.unpack_from(data, footer + 9)
    if not len(MAGIC) <= pos < footer:
        raise _Unsupported("no summary section")
    summary = _Summary()
    while pos < footer:
        opcode, (length,) = data[pos], _U64.unpack_from(data, pos + 1)
        body = pos + 9
        if opcode == _OP_CHANNEL:
            (channel_id,) = _U16.unpack_from(data, body)
            summary.topics[channel_id] = _string(data, body + 4)[0]
        elif opcode == _OP_CHUNK_INDEX:
            _on_chunk_index(summary, data, body)
        elif opcode == _OP_STATISTICS:
            _on_statistics(summary, data, body)
        pos = body + length
    if pos != footer or summary.counts is None:
        raise _Unsupported("summary without statistics, or not ending at the footer")
    return summary


def _chunk_records(data: bytes, offset: int) -> tuple[int, int]:
    """Byte range of an uncompressed chunk's records, after checking its size and CRC."""
    if data[offset] != _OP_CHUNK:
        raise _Unsupported("chunk index pointing elsewhere than at a chunk")
    _, _, raw_size, crc = struct.unpack_from("<QQQI", data, offset + 9)
    compression, pos = _string(data, offset + 9 + 28)
    (size,) = _U64.unpack_from(data, pos)
    start = pos + 8
    if compression or size != raw_size or start + size > len(data):
        raise _Unsupported("compressed or oversized chunk")
    if crc and zlib.crc32(memoryview(data)[start:start + size]) != crc:
        raise _Unsupported("chunk CRC")
    return start, start + size


def _index_entries(data: bytes, offset: int, channel_id: int) -> NDArray[np.uint64]:
    """(n, 2) log time and chunk-relative offset of one Message Index record."""
    if data[offset] != _OP_MESSAGE_INDEX or _U16.unpack_from(data, offset + 9)[0] != channel_id:
        raise _Unsupported("message index offset pointing elsewhere")
    (size,) = _U32.unpack_from(data, offset + 11)
    if size % 16 or offset + 15 + size > len(data):
        raise _Unsupported("message index size")
    return np.frombuffer(data, np.dtype("<u8"), size // 8, offset + 15).reshape(-1, 2)


def _gather(data: bytes, at: NDArray[np.int64], dtype: str) -> NDArray[np.int64]:
    """The little-endian integer of type ``dtype`` at each byte offset ``at`` (one unaligned view, one gather)."""
    size = np.dtype(dtype).itemsize
    every_byte = np.ndarray((len(data) - size + 1,), np.dtype(dtype), buffer=data, strides=(1,))
    return every_byte[at].astype(np.int64)


def locate_messages(data: bytes, topics: Collection[str]) -> MessageLocations | None:
    """Locate every message of ``topics`` in the MCAP file ``data``; ``None`` when the file is not one to trust.

    Parameters
    ----------
    data
        The whole file.
    topics
        Topic names; a topic the file lacks has no messages.

    Returns
    -------
    MessageLocations or None
        ``None`` when the file is compressed, lacks indexes or statistics, has a
        topic on several channels, or an index that disagrees with its records.
    """
    try:
        return _locate(data, set(topics))
    except (_Unsupported, struct.error, IndexError, ValueError):
        return None


def _locate(data: bytes, topics: set[str]) -> MessageLocations:
    summary = _read_summary(data)
    wanted = {cid: topic for cid, topic in summary.topics.items() if topic in topics}
    if len(set(wanted.values())) != len(wanted):
        raise _Unsupported("a topic on several channels")
    parts: list[tuple[int, NDArray[np.uint64], int, int, int, int]] = []
    for start_ns, end_ns, chunk_offset, indexes, compression in summary.chunks:
        if compression or not any(cid in wanted for cid in indexes):
            if compression:
                raise _Unsupported("compressed chunk")
            continue
        begin, end = _chunk_records(data, chunk_offset)
        parts.extend((cid, _index_entries(data, offset, cid), begin, end, start_ns, end_ns)
                     for cid, offset in indexes.items() if cid in wanted)
    return _checked(data, wanted, summary.counts or {}, parts)


def _checked(data: bytes, wanted: dict[int, str], counts: dict[int, int],
             parts: list[tuple[int, NDArray[np.uint64], int, int, int, int]]) -> MessageLocations:
    """Check every indexed record at once and put the messages in rosbags' order."""
    sizes = [len(entries) for _, entries, *_ in parts]
    found = dict.fromkeys(wanted, 0)
    for (cid, *_), n in zip(parts, sizes, strict=True):
        found[cid] += n
    if any(found[cid] != counts.get(cid, 0) for cid in wanted):
        raise _Unsupported("message indexes disagree with the statistics")
    entries = np.concatenate([p[1] for p in parts]) if parts else np.zeros((0, 2), np.uint64)
    channel, begin, end, first_ns, last_ns = (np.repeat(np.array([p[i] for p in parts], np.int64), sizes)
                                              for i in (0, 2, 3, 4, 5))
    log_ns, at = entries[:, 0].astype(np.int64), entries[:, 1].astype(np.int64) + begin
    if at.size and (at.min() < 0 or (at + _MESSAGE_HEAD_BYTES > end).any()):
        raise _Unsupported("message index offset outside its chunk")
    length = _gather(data, at + 1, "<u8")
    good = ((_gather(data, at, "u1") == _OP_MESSAGE) & (length >= 22) & (at + 9 + length <= end)
            & (_gather(data, at + 9, "<u2") == channel) & (_gather(data, at + 15, "<u8") == log_ns))
    in_file = np.argsort(at)
    if not good.all() or (at[in_file][1:] < (at + 9 + length)[in_file][:-1]).any():
        raise _Unsupported("a message index entry that is not a message of its channel, or records that overlap")
    keep = (log_ns >= first_ns) & (log_ns <= last_ns)  # rosbags reads a chunk's messages within its times only
    order = np.lexsort((at[keep], log_ns[keep]))
    start = (at + _MESSAGE_HEAD_BYTES)[keep][order]
    return MessageLocations(wanted, channel[keep][order], log_ns[keep][order], start,
                            (at + 9 + length)[keep][order])
