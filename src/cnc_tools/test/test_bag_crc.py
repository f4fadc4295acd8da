"""Bags carry CRCs and small chunks: a flipped byte is found, a cut file keeps the ticks before the cut.

Also: ``metadata.yaml`` holds the offered QoS profiles and ``ros_distro: jazzy`` as rosbag2 writes them.
"""
from __future__ import annotations

import struct
from pathlib import Path

import pytest
from numpy.testing import assert_array_equal
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag2 import Reader
from ruamel.yaml import YAML

from cnc_contour_control.core.errors import BagError
from cnc_tools.bagio.bag import read_bag
from cnc_tools.bagio.mcap_salvage import crc_problem
from cnc_tools.bagio.mcap_storage import CHUNK_SIZE_BYTES

TICKS = 2000
#: Offsets of single flipped bytes, as fractions of the file: header, chunks, message indexes, summary.
FLIP_AT = (0.0001, 0.002, 0.1, 0.25, 0.3333, 0.5, 0.61, 0.75, 0.9, 0.97, 0.995, 0.9995)


@pytest.fixture(scope="module")
def bag_bytes(circle_bag: Path) -> tuple[bytes, str]:
    """The session circle bag's .mcap bytes and metadata.yaml text."""
    return (circle_bag / "circle.mcap").read_bytes(), (circle_bag / "metadata.yaml").read_text()


def _copy(tmp: Path, data: bytes, metadata: str) -> Path:
    bag = tmp / "circle"
    bag.mkdir()
    (bag / "circle.mcap").write_bytes(data)
    (bag / "metadata.yaml").write_text(metadata)
    return bag


def _message_index_offset(data: bytes) -> int:
    """Offset of the first MessageIndex record's body (outside every chunk: only the data CRC covers it)."""
    pos = 8
    while data[pos] != 0x07:
        pos += 9 + struct.unpack_from("<Q", data, pos + 1)[0]
    return pos + 9 + 12  # inside its first (log time, offset) entry


def test_an_intact_bag_passes_its_crcs(bag_bytes: tuple[bytes, str]) -> None:
    data, _ = bag_bytes
    assert crc_problem(data) == ""
    footer_crc = struct.unpack_from("<I", data, len(data) - 8 - 4)[0]
    assert footer_crc != 0, "the summary CRC is computed"


@pytest.mark.parametrize("where", [*FLIP_AT, "message index"])
def test_a_flipped_byte_is_never_read_as_complete(tmp_path: Path, bag_bytes: tuple[bytes, str], where: object) -> None:
    data, metadata = bag_bytes
    offset = _message_index_offset(data) if where == "message index" else int(float(where) * len(data))  # type: ignore[arg-type]  # a float or 'message index'
    damaged = bytearray(data)
    damaged[offset] ^= 0x01
    assert crc_problem(bytes(damaged)) != ""
    try:
        run = read_bag(_copy(tmp_path, bytes(damaged), metadata))
    except BagError as err:
        assert "INCOMPLETE" in str(err) or "circle" in str(err)
        return
    assert not run.integrity.complete and run.integrity.method == "scan"
    assert any("CRC" in p or "footer" in p for p in run.integrity.problems), run.integrity.problems


def test_a_bag_cut_in_half_keeps_the_ticks_before_the_cut(tmp_path: Path, bag_bytes: tuple[bytes, str],
                                                          circle_bag: Path) -> None:
    data, metadata = bag_bytes
    whole = read_bag(circle_bag)
    summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 20)[0]  # the Footer's first field
    cut = len(data) // 2
    run = read_bag(_copy(tmp_path, data[:cut], metadata))
    kept = run.joint_states.stamp_ns.size
    ticks_before_cut = TICKS * cut / summary_start
    ticks_per_chunk = TICKS * CHUNK_SIZE_BYTES / summary_start
    assert kept >= ticks_before_cut - ticks_per_chunk - 1, "at most the chunk in progress at the cut is lost"
    assert kept > 0.4 * TICKS
    assert_array_equal(run.joint_states.position_m, whole.joint_states.position_m[:kept])
    assert run.integrity.lost["/cnc/joint_states"] == TICKS - kept


def test_metadata_yaml_is_as_rosbag2_writes_it(circle_bag: Path) -> None:
    info = YAML(typ="safe").load((circle_bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["ros_distro"] == "jazzy"
    for entry in info["topics_with_message_count"]:
        profiles = entry["topic_metadata"]["offered_qos_profiles"]
        assert len(profiles) == 1 and profiles[0]["reliability"] == "reliable", entry["topic_metadata"]["name"]
    with Reader(circle_bag) as reader:
        assert reader.ros_distro == "jazzy"
        qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}  # type: ignore[union-attr]  # rosbag2 connections have it
    assert qos["/cnc/path"][0].durability == QosDurability.TRANSIENT_LOCAL
    assert qos["/cnc/joint_states"][0].durability == QosDurability.VOLATILE
    assert qos["/cnc/joint_states"][0].depth == 1000
    assert all(p[0].reliability == QosReliability.RELIABLE for p in qos.values())


def test_the_mcap_metadata_record_says_jazzy_too(bag_bytes: tuple[bytes, str]) -> None:
    data, _ = bag_bytes
    assert b"ros_distro: jazzy" in data and b"ros_distro: rosbags" not in data
