"""Our MCAP writer writes the ``mcap`` library's bytes; bags through the direct path read back whole.

Against ``mcap.writer.Writer`` with the storage's options: random sequences of
messages (0 to 200 kB, sizes around the chunk limit), flushes, channels
registered mid-run and a metadata record give the same file bytes; the mcap
reader (CRCs validated), rosbags and the salvage scan read every message back;
a flipped byte is found; a cut file keeps its whole chunks. ``BagWriter``'s
direct path gives the same ``.mcap`` and ``metadata.yaml`` as rosbags' path.
"""
from __future__ import annotations

import io
import struct
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap.writer import CompressionType
from mcap.writer import Writer as LibraryWriter
from rosbags.highlevel import AnyReader

from cnc_tools.bagio.bag import BagWriter
from cnc_tools.bagio.mcap_salvage import crc_problem, scan_mcap
from cnc_tools.bagio.mcap_storage import CHUNK_SHARE, CHUNK_SIZE_BYTES
from cnc_tools.bagio.mcap_writer import McapWriter
from cnc_tools.bench.bag_write import LibraryBagWriter, run_messages

#: Message sizes that put a chunk just under, at and just over its limit (header 31 bytes per message).
_EDGE_SIZES = [0, 1, CHUNK_SIZE_BYTES - 31 - 1, CHUNK_SIZE_BYTES - 31, CHUNK_SIZE_BYTES - 31 + 1, 200_000]
_SIZES = st.one_of(st.sampled_from(_EDGE_SIZES), st.integers(0, 3000), st.integers(0, 200_000))
_MESSAGE = st.tuples(st.just("message"), st.integers(0, 2), st.integers(0, 2**40), _SIZES)
_OP = st.one_of(_MESSAGE, _MESSAGE, _MESSAGE, st.just(("flush",)), st.just(("channel",)), st.just(("metadata",)))


def _library(stream: io.BytesIO) -> LibraryWriter:
    return LibraryWriter(stream, chunk_size=CHUNK_SIZE_BYTES, compression=CompressionType.NONE,
                         enable_crcs=True, enable_data_crcs=True)


def _play(writer: McapWriter | LibraryWriter, ops: list[tuple]) -> list[tuple[str, int, bytes]]:
    """Run ``ops`` on ``writer``; the messages written as (topic, log time, data)."""
    writer.start(profile="ros2", library="test")
    schema = writer.register_schema("std_msgs/msg/String", "ros2msg", b"string data")
    channels = [writer.register_channel(f"/t{k}", "cdr", schema, {"offered_qos_profiles": f"q{k}"})
                for k in range(2)]
    written = []
    for op in ops:
        if op[0] == "message":
            channel_id = channels[op[1] % len(channels)]
            data = bytes([op[2] % 251]) * op[3]
            writer.add_message(channel_id, op[2], data, op[2])
            written.append((f"/t{channel_id - 1}", op[2], data))
        elif op[0] == "flush":
            writer.flush()
        elif op[0] == "channel":
            channels.append(writer.register_channel(f"/t{len(channels)}", "cdr", schema, {}))
        else:
            writer.add_metadata("note", {"k": str(len(written))})
    writer.finish()
    return written


def _files(ops: list[tuple]) -> tuple[bytes, bytes, list[tuple[str, int, bytes]]]:
    ours, theirs = io.BytesIO(), io.BytesIO()
    written = _play(McapWriter(ours, CHUNK_SIZE_BYTES), ops)
    _play(_library(theirs), ops)
    return ours.getvalue(), theirs.getvalue(), written


#: After a flush the chunk is empty: records of exactly the limit, and one byte over it.
_AT_THE_LIMIT = [("message", 0, 5, 10), ("flush",), ("message", 1, 4, CHUNK_SIZE_BYTES - 31), ("message", 0, 3, 0),
                 ("message", 1, 9, CHUNK_SIZE_BYTES - 30), ("message", 0, 2, 1)]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_OP, max_size=40))
@example(_AT_THE_LIMIT)
def test_the_file_is_the_libraries_byte_for_byte_and_reads_back(ops: list[tuple]) -> None:
    ours, theirs, written = _files(ops)
    assert ours == theirs
    reader = make_reader(io.BytesIO(ours), validate_crcs=True)
    read = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)]
    assert read == written
    assert crc_problem(ours) == ""


def _bag(path: Path, kind: type[BagWriter], n_messages: int) -> Path:
    topics, messages = run_messages(path.parent / f"{path.name}-source", n_messages)
    with kind(path, topics) as bag:
        for topic, stamp_ns, data in messages:
            bag.write(topic, stamp_ns, data)
        bag.flush()
        assert sum(bag.message_counts.values()) == n_messages
    return path


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The same 6000 messages of a 1 kHz 2-axis run through the direct path and through rosbags + mcap."""
    root = tmp_path_factory.mktemp("bags")
    return _bag(root / "direct" / "run", BagWriter, 6000), _bag(root / "library" / "run", LibraryBagWriter, 6000)


def test_the_direct_path_writes_what_rosbags_writes(bags: tuple[Path, Path]) -> None:
    """The same records and metadata; the bytes differ only where the direct path's chunks grow with the file
    (CHUNK_SHARE: the library writes fixed-size chunks; the writer's own byte-for-byte test is above)."""
    direct, library = bags
    assert (direct / "metadata.yaml").read_text() == (library / "metadata.yaml").read_text()
    ours, theirs = (make_reader(io.BytesIO((bag / "run.mcap").read_bytes()), validate_crcs=True) for bag in bags)
    assert [(c.topic, s.name, m.log_time, m.data) for s, c, m in ours.iter_messages(log_time_order=False)] == \
        [(c.topic, s.name, m.log_time, m.data) for s, c, m in theirs.iter_messages(log_time_order=False)]
    chunks = [len(_chunk_spans((bag / "run.mcap").read_bytes())) for bag in bags]
    assert chunks[0] < chunks[1], f"growing chunks: {chunks[0]} against the library's {chunks[1]}"
    with AnyReader([direct]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert sum(1 for _ in reader.messages()) == 6000 == sum(counts.values())
    assert counts["/clock"] == 1200


def test_a_flipped_byte_is_found(bags: tuple[Path, Path]) -> None:
    data = bytearray((bags[0] / "run.mcap").read_bytes())
    for offset in (100, len(data) // 3, len(data) - 100):
        damaged = bytearray(data)
        damaged[offset] ^= 0x10
        assert crc_problem(bytes(damaged)) != "", offset


def test_a_cut_file_salvages_its_whole_chunks(tmp_path: Path, bags: tuple[Path, Path]) -> None:
    data = (bags[0] / "run.mcap").read_bytes()
    summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 20)[0]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: summary_start // 2])
    kept: list[int] = []
    scan, problem = scan_mcap(cut, lambda topic: True, lambda topic, stamp, raw: kept.append(stamp))
    whole = [m.log_time for _, _, m in make_reader(io.BytesIO(data)).iter_messages(log_time_order=False)]
    assert "truncated" in problem or "ends" in problem, problem
    chunk_messages = max(1, len(whole) * max(CHUNK_SIZE_BYTES, int(CHUNK_SHARE * summary_start)) // summary_start)
    assert len(whole) // 2 - 2 * chunk_messages <= len(kept) < len(whole)
    assert kept == whole[: len(kept)]


def _chunk_spans(data: bytes) -> list[tuple[int, int]]:
    """(offset, length) of every Chunk record of an MCAP file, walking its records from the magic."""
    spans, offset = [], 8
    while offset + 9 <= len(data):
        opcode, length = data[offset], struct.unpack_from("<Q", data, offset + 1)[0]
        if opcode == 0x06:
            spans.append((offset, 9 + length))
        if opcode == 0x0F:  # the footer
            break
        offset += 9 + length
    return spans


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.integers(0, 3000), min_size=1, max_size=3000), st.sampled_from([1 / 200, 1 / 50]))
def test_growing_chunks_stay_within_their_share_of_the_file_and_read_back(sizes: list[int], share: float) -> None:
    stream = io.BytesIO()
    written = _play(McapWriter(stream, CHUNK_SIZE_BYTES, max_share=share),
                    [("message", k % 2, k, size) for k, size in enumerate(sizes)])
    data = stream.getvalue()
    reader = make_reader(io.BytesIO(data), validate_crcs=True)
    assert [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)] == written
    for offset, length in _chunk_spans(data):
        records = length - 9 - 8 * 3 - 4 - 4 - 8  # the chunk record's fixed fields and its empty compression
        limit = max(CHUNK_SIZE_BYTES, int(share * offset))
        assert records <= limit + 31 + 3000, "a chunk closes with the message that crossed its limit"
