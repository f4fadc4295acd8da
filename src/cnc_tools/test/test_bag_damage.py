"""A damaged bag loses the chunk the damage lies in, not what follows it (issue 22).

A real bag (a synthetic 2-axis 1 kHz circle run recorded with the project's
writer, ~400 chunks) gets one flipped bit: in a chunk's records, in a chunk's
length, in the first chunk (which holds the Schema and Channel records), in a
Message Index. Every message outside the damaged chunk is read back, the bag is
judged partial, and its integrity names the topics and counts what was lost.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from cnc_contour_control.core.errors import BagError
from cnc_tools.analysis.verdict import judge
from cnc_tools.bagio.bag import read_bag
from cnc_tools.bagio.raw_bag import locate, read_raw
from cnc_tools.bagio.synthetic import circle_program, circle_trajectory, write_run_bag
from cnc_tools.run_record import RunRecord

TICKS = 2000
JOINT_STATES = "/cnc/joint_states"


@dataclass(frozen=True)
class Chunk:
    """A Chunk record of the file: where it lies, where its records lie, its message times and count."""

    offset: int
    records_start: int
    end: int
    start_ns: int
    end_ns: int
    messages: int


def chunks_of(data: bytes) -> list[Chunk]:
    """The chunks of an MCAP file, walking its top-level records up to the summary."""
    summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 20)[0]
    found, pos = [], 8
    while pos < summary_start:
        length = struct.unpack_from("<Q", data, pos + 1)[0]
        if data[pos] == 0x06:
            start_ns, end_ns = struct.unpack_from("<QQ", data, pos + 9)
            records_start = pos + 9 + 40
            messages, at = 0, records_start
            while at < pos + 9 + length:
                messages += data[at] == 0x05
                at += 9 + struct.unpack_from("<Q", data, at + 1)[0]
            found.append(Chunk(pos, records_start, pos + 9 + length, start_ns, end_ns, messages))
        pos += 9 + length
    return found


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> tuple[bytes, str, RunRecord]:
    """The .mcap bytes and metadata.yaml text of a 2000-tick circle bag, and the run read from it whole."""
    path = write_run_bag(tmp_path_factory.mktemp("bags") / "circle", circle_program(), circle_trajectory(0.02, 5e-6))
    return (path / "circle.mcap").read_bytes(), (path / "metadata.yaml").read_text(), read_bag(path)


def _damaged_copy(tmp_path: Path, data: bytes, metadata: str, offset: int, bit: int = 0) -> Path:
    damaged = bytearray(data)
    damaged[offset] ^= 1 << bit
    folder = tmp_path / "circle"
    folder.mkdir()
    (folder / "circle.mcap").write_bytes(bytes(damaged))
    (folder / "metadata.yaml").write_text(metadata)
    return folder


def _middle_chunk(data: bytes) -> Chunk:
    every = chunks_of(data)
    return next(c for c in every if c.end > len(data) // 2)


def test_the_bag_has_hundreds_of_small_chunks(bag: tuple[bytes, str, RunRecord]) -> None:
    data, _, _ = bag
    every = chunks_of(data)
    assert len(every) >= 100
    assert max(c.messages for c in every) <= 0.01 * 4 * TICKS, "one chunk holds <= 1 % of the run's messages"


def test_a_flipped_bit_mid_file_loses_only_its_chunk(tmp_path: Path, bag: tuple[bytes, str, RunRecord]) -> None:
    data, metadata, whole = bag
    chunk = _middle_chunk(data)
    run = read_bag(_damaged_copy(tmp_path, data, metadata, (chunk.records_start + chunk.end) // 2, bit=4))
    integrity = run.integrity
    assert not integrity.complete and integrity.method == "scan"
    lost = integrity.lost
    assert lost is not None and 0 < sum(lost.values()) <= chunk.messages
    stamps = whole.joint_states.stamp_ns
    after = stamps[stamps > chunk.end_ns]
    assert after.size > 0.4 * TICKS
    assert np.isin(after, run.joint_states.stamp_ns).all(), "every tick after the damaged chunk is read"
    assert np.isin(stamps[stamps < chunk.start_ns], run.joint_states.stamp_ns).all()
    assert judge(run).status == "partial"
    text = integrity.describe()
    assert f"{JOINT_STATES}: {lost[JOINT_STATES]}" in text and f"chunk at byte {chunk.offset} fails its CRC" in text


def test_a_flipped_bit_in_a_chunk_length_resynchronises(tmp_path: Path, bag: tuple[bytes, str, RunRecord]) -> None:
    data, metadata, whole = bag
    chunk = _middle_chunk(data)
    run = read_bag(_damaged_copy(tmp_path, data, metadata, chunk.offset + 2, bit=3))  # record length += 2 KiB
    lost = run.integrity.lost
    assert lost is not None and 0 < sum(lost.values()) <= chunk.messages
    assert run.joint_states.stamp_ns[-1] == whole.joint_states.stamp_ns[-1]
    assert judge(run).status == "partial"


def test_a_flipped_bit_in_the_first_chunk_keeps_the_rest_and_names_the_lost_path(
        tmp_path: Path, bag: tuple[bytes, str, RunRecord]) -> None:
    data, metadata, _ = bag
    first = chunks_of(data)[0]
    folder = _damaged_copy(tmp_path, data, metadata, first.records_start + 40)  # inside the Schema records
    raw, integrity = read_raw(locate(folder), lambda topic: True)
    assert len(raw.data[JOINT_STATES]) >= TICKS - first.messages, "the channels come from the summary"
    assert integrity.lost is not None and integrity.lost["/cnc/path"] == 1
    with pytest.raises(BagError, match=r"no /cnc/path message.*INCOMPLETE.*/cnc/path: 1"):
        read_bag(folder)


def test_a_flipped_bit_in_a_message_index_loses_nothing(tmp_path: Path, bag: tuple[bytes, str, RunRecord]) -> None:
    data, metadata, whole = bag
    chunk = _middle_chunk(data)
    assert data[chunk.end] == 0x07, "a Message Index follows its chunk"
    run = read_bag(_damaged_copy(tmp_path, data, metadata, chunk.end + 3, bit=1))  # its record length
    assert run.integrity.lost == dict.fromkeys(run.integrity.found, 0)
    assert not run.integrity.complete and judge(run).status == "partial"
    assert run.joint_states.stamp_ns.size == whole.joint_states.stamp_ns.size


def test_a_damaged_schema_in_the_summary_is_not_taken(tmp_path: Path, bag: tuple[bytes, str, RunRecord]) -> None:
    """Found by bench fuzz: the scan took the summary's Schema records although the summary failed its CRC."""
    data, metadata, whole = bag
    summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 20)[0]
    at = data.index(b"float64", summary_start)
    run = read_bag(_damaged_copy(tmp_path, data, metadata, at, bit=1))  # "float64" -> "dloat64"
    assert run.integrity.lost == dict.fromkeys(run.integrity.found, 0)
    assert judge(run).status == "partial"
    np.testing.assert_array_equal(run.joint_states.position_m, whole.joint_states.position_m)
