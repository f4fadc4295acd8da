"""The indexed read (``mcap_index``) gives rosbags' messages in rosbags' order and refuses files it cannot vouch for."""
from __future__ import annotations

import io
import struct
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.writer import CompressionType
from mcap.writer import Writer as LibraryWriter
from rosbags.highlevel import AnyReader

from cnc_tools.bagio.mcap_index import locate_messages
from cnc_tools.bagio.mcap_storage import CHUNK_SIZE_BYTES
from cnc_tools.bagio.mcap_writer import McapWriter
from cnc_tools.bagio.typestore import project_typestore

TOPICS = ("/a", "/b", "/c")
#: (topic index, log time ns, size): log times collide and run backwards, sizes cross the chunk limit.
_MESSAGES = st.lists(st.tuples(st.integers(0, 2), st.integers(0, 50), st.integers(0, CHUNK_SIZE_BYTES // 3)),
                     max_size=40)


def _write(writer: McapWriter | LibraryWriter, messages: list[tuple[int, int, int]]) -> None:
    writer.start(profile="ros2", library="test")
    schema = writer.register_schema("std_msgs/msg/String", "ros2msg", b"string data")
    channels = [writer.register_channel(topic, "cdr", schema, {}) for topic in TOPICS]
    for n, (topic, log_time_ns, size) in enumerate(messages):
        writer.add_message(channels[topic], log_time_ns, bytes([n % 251]) * size, log_time_ns)
    writer.finish()


def _file(tmp_path: Path, messages: list[tuple[int, int, int]], compression: CompressionType | None = None) -> Path:
    stream = io.BytesIO()
    _write(McapWriter(stream, CHUNK_SIZE_BYTES) if compression is None else
           LibraryWriter(stream, chunk_size=CHUNK_SIZE_BYTES, compression=compression), messages)
    path = tmp_path / "file.mcap"
    path.write_bytes(stream.getvalue())
    return path


def _rosbags(path: Path, topics: tuple[str, ...]) -> list[tuple[str, int, bytes]]:
    with AnyReader([path], default_typestore=project_typestore()) as reader:
        wanted = [c for c in reader.connections if c.topic in topics]
        return [(c.topic, t, bytes(d)) for c, t, d in reader.messages(connections=wanted)] if wanted else []


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(messages=_MESSAGES, topics=st.sets(st.sampled_from(TOPICS), min_size=1))
def test_the_indexed_read_gives_rosbags_messages_in_rosbags_order(tmp_path: Path, messages: list[tuple[int, int, int]],
                                                                  topics: set[str]) -> None:
    path = _file(tmp_path, messages)
    data = path.read_bytes()
    found = locate_messages(data, topics)
    assert found is not None
    ours = [(found.topics[int(c)], int(t), data[a:b])
            for c, t, a, b in zip(found.channel, found.log_time_ns, found.start, found.end, strict=True)]
    assert ours == _rosbags(path, tuple(sorted(topics)))


def test_a_compressed_file_is_left_to_rosbags(tmp_path: Path) -> None:
    path = _file(tmp_path, [(0, 1, 10), (1, 2, 20)], CompressionType.ZSTD)
    assert locate_messages(path.read_bytes(), TOPICS) is None
    assert len(_rosbags(path, TOPICS)) == 2


def test_an_index_entry_pointing_elsewhere_is_refused(tmp_path: Path) -> None:
    data = bytearray(_file(tmp_path, [(0, 1, 10), (0, 2, 10)]).read_bytes())
    index = data.index(bytes([0x07]) + struct.pack("<QH", 2 + 4 + 32, 1))  # channel 1's Message Index, two entries
    offset_at = index + 9 + 2 + 4 + 8 + 8 + 8  # the second entry's offset
    struct.pack_into("<Q", data, offset_at, struct.unpack_from("<Q", data, offset_at)[0] + 1)
    assert locate_messages(bytes(data), TOPICS) is None


def _summary_record(data: bytes, opcode: int) -> int:
    """Offset of the first summary record with ``opcode`` (the footer gives where the summary starts)."""
    (pos,) = struct.unpack_from("<Q", data, len(data) - 8 - 20 + 0)
    while data[pos] != opcode:
        pos += 9 + struct.unpack_from("<Q", data, pos + 1)[0]
    return pos


def test_indexes_that_miss_a_message_the_statistics_count_are_refused(tmp_path: Path) -> None:
    data = bytearray(_file(tmp_path, [(0, 1, 10), (0, 2, 10)]).read_bytes())
    counts = _summary_record(bytes(data), 0x0B) + 9 + 46  # the Statistics record's first channel count
    struct.pack_into("<HQ", data, counts, 1, 3)  # says three messages on channel 1
    assert locate_messages(bytes(data), TOPICS) is None
