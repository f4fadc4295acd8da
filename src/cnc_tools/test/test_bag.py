"""Bag writing and reading: round trips through rosbags and mcap, refusals, salvage of damaged files."""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from numpy.testing import assert_allclose, assert_array_equal
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from ruamel.yaml import YAML

from cnc_contour_control.core.errors import BagError, ConfigError
from cnc_tools.bagio.bag import BagWriter, read_bag
from cnc_tools.bagio.typestore import (
    candidate_msg_dirs,
    custom_type_definitions,
    decode_columns,
    find_msg_dir,
    project_typestore,
)

SETTINGS = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@pytest.fixture(scope="module")
def circle(synth):
    return synth.circle_program(), synth.circle_trajectory(0.02, 5e-6)


@pytest.fixture(scope="module")
def bag_bytes(circle_bag: Path) -> tuple[bytes, str]:
    """The session circle bag's .mcap bytes and metadata.yaml text."""
    return (circle_bag / "circle.mcap").read_bytes(), (circle_bag / "metadata.yaml").read_text()


def _copy(tmp: Path, data: bytes, metadata: str | None) -> Path:
    bag = tmp / "circle"
    bag.mkdir()
    (bag / "circle.mcap").write_bytes(data)
    if metadata is not None:
        (bag / "metadata.yaml").write_text(metadata)
    return bag


# --------------------------------------------------------------------------- layout and round trips
def test_layout_is_rosbag2_mcap(circle_bag: Path) -> None:
    assert sorted(p.name for p in circle_bag.iterdir()) == ["circle.mcap", "metadata.yaml"]
    info = YAML(typ="safe").load((circle_bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    assert info["relative_file_paths"] == ["circle.mcap"]
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    assert counts["/cnc/joint_states"] == 2000 and counts["/cnc/path"] == 1
    qos = {t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"]
           for t in info["topics_with_message_count"]}
    assert "transient_local" in str(qos["/cnc/path"])


def test_mcap_library_decodes_every_message(circle_bag: Path, circle) -> None:
    program, traj = circle
    with (circle_bag / "circle.mcap").open("rb") as stream:
        reader = make_reader(stream, validate_crcs=True, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
        positions, paths = [], []
        for _, channel, _, decoded in reader.iter_decoded_messages(topics=["/cnc/joint_states", "/cnc/path"]):
            (paths if channel.topic == "/cnc/path" else positions).append(decoded)
    assert_array_equal(np.array([m.position for m in positions]), traj.position_m)
    assert [m.name for m in positions[:1]] == [["x", "y"]]
    assert paths[0].program_name == "circle" and paths[0].segments[0].kind == 2
    assert_allclose(paths[0].segments[0].start_m, program.segments[0].start_m)


def test_rosbags_reads_back_what_was_written(circle_bag: Path, circle) -> None:
    _, traj = circle
    with AnyReader([circle_bag], default_typestore=project_typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == "/cnc/reference"]
        refs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    assert_array_equal(np.array([r.position_m for r in refs]), traj.reference_m)
    assert_array_equal(np.array([r.header.stamp.nanosec for r in refs]) % 1_000_000, 0)


def test_read_bag_returns_the_recorded_arrays(circle_bag: Path, circle) -> None:
    program, traj = circle
    run = read_bag(circle_bag)
    assert run.integrity.complete and run.integrity.method == "index"
    assert run.integrity.lost == dict.fromkeys(run.integrity.found, 0)
    assert run.name == "circle" and run.axis_names == ("x", "y")
    assert_array_equal(run.joint_states.stamp_ns, traj.stamp_ns)
    assert_array_equal(run.joint_states.position_m, traj.position_m)
    assert_array_equal(run.reference.position_m, traj.reference_m)
    assert_array_equal(run.reference.velocity_m_s, traj.reference_velocity_m_s)
    assert sorted(run.commands) == ["x", "y"]
    x = run.commands["x"]
    assert (x.law, x.command_unit) == ("pid", "dac")
    assert_allclose(x.error_m, traj.reference_m[:, 0] - traj.position_m[:, 0])
    assert_allclose(run.program.segments[0].radius_m, program.segments[0].radius_m)
    assert run.program.name == "circle"


def test_read_without_commands_skips_them(circle_bag: Path) -> None:
    run = read_bag(circle_bag, commands=False)
    assert run.commands == {}
    assert "/cnc/servo/x/command" not in run.integrity.found


def test_joint_names_in_another_order_with_extra_axes(tmp_path: Path, synth) -> None:
    program, traj = synth.circle_program(), synth.circle_trajectory(0.02, 0.0, n=50)
    bag = synth.write_run_bag(tmp_path / "b", program, traj, joint_names=("spindle", "y", "x"), commands=False)
    assert_array_equal(read_bag(bag).joint_states.position_m, traj.position_m)


# --------------------------------------------------------------------------- refusals
def test_missing_path_topic_is_refused_by_name(tmp_path: Path, synth) -> None:
    bag = synth.write_run_bag(tmp_path / "b", synth.circle_program(), synth.circle_trajectory(0.02, 0.0, n=20),
                              with_path=False)
    with pytest.raises(BagError, match="/cnc/path"):
        read_bag(bag)


def test_joint_states_lacking_a_path_axis_is_refused_by_name(tmp_path: Path, synth) -> None:
    program, traj = synth.circle_program(n_axes=3), synth.circle_trajectory(0.02, 0.0, n=20, n_axes=3)
    bag = synth.write_run_bag(tmp_path / "b", program, traj, joint_names=("x", "y"), commands=False)
    with pytest.raises(BagError, match=r"/cnc/joint_states lacks axes \['z'\]"):
        read_bag(bag)


def test_a_bag_recorded_with_an_older_type_lacking_a_field_is_refused_by_name(tmp_path: Path, synth) -> None:
    name = "cnc_contour_interfaces/msg/Reference"
    old_text = (find_msg_dir() / "Reference.msg").read_text().replace("bool done", "# (no done field yet)")
    definitions = {**custom_type_definitions(find_msg_dir()), **get_types_from_msg(old_text, name)}
    old_store = get_typestore(Stores.ROS2_JAZZY)
    old_store.register(definitions)
    program = synth.circle_program()
    topics = {k: v for k, v in synth.TOPICS.items() if k != "/clock"}
    with BagWriter(tmp_path / "old", topics, typestore=old_store) as writer:
        writer.write_message("/cnc/path", 0, synth.path_message(program))
        writer.write_message("/cnc/joint_states", 1, synth.joint_state(1, ["x", "y"], np.zeros(2), np.zeros(2)))
        reference = old_store.types[name](
            header=synth.header(1, "machine"), axis_names=["x", "y"], position_m=np.zeros(2),
            velocity_m_s=np.zeros(2), acceleration_m_s2=np.zeros(2), path_length_m=0.0, segment_index=0,
            feed_m_s=0.0, programmed_feed_m_s=0.0, feed_override_ratio=1.0)
        writer.write_message("/cnc/reference", 1, reference)
    with pytest.raises(BagError, match=r"/cnc/reference: the recorded .*Reference has no fields \['done'\]"):
        read_bag(tmp_path / "old")


def test_writer_refuses_an_existing_folder_and_leaves_it_alone(tmp_path: Path) -> None:
    existing = tmp_path / "run"
    existing.mkdir()
    (existing / "keep.txt").write_text("mine")
    with pytest.raises(BagError, match=str(existing)):
        BagWriter(existing, {"/cnc/joint_states": "sensor_msgs/msg/JointState"})
    assert [p.name for p in existing.iterdir()] == ["keep.txt"]


def test_writer_refuses_unknown_topics_types_and_writes_after_close(tmp_path: Path, synth) -> None:
    with pytest.raises(BagError, match="no_such_msgs/msg/Thing"):
        BagWriter(tmp_path / "a", {"/t": "no_such_msgs/msg/Thing"})
    writer = BagWriter(tmp_path / "b", {"/cnc/joint_states": "sensor_msgs/msg/JointState"})
    with pytest.raises(BagError, match="'/cnc/other' was not declared"):
        writer.write("/cnc/other", 0, b"\x00\x01\x00\x00")
    writer.write_message("/cnc/joint_states", 5, synth.joint_state(5, ["x"], np.ones(1), np.ones(1)))
    writer.add_topic("/cnc/servo/x/command", synth.COMMAND_TYPE)
    writer.write_message("/cnc/servo/x/command", 5, synth.axis_command(5, "x", 1.0, 0.0))
    with pytest.raises(BagError, match="declared already"):
        writer.add_topic("/cnc/servo/x/command", synth.COMMAND_TYPE)
    writer.close()
    writer.close()
    assert writer.message_counts == {"/cnc/joint_states": 1, "/cnc/servo/x/command": 1}
    with pytest.raises(BagError, match="closed"):
        writer.write("/cnc/joint_states", 6, b"")


def test_missing_bag_is_a_bag_error(tmp_path: Path) -> None:
    with pytest.raises(BagError, match="does not exist"):
        read_bag(tmp_path / "nothing")


# --------------------------------------------------------------------------- salvage
def test_cut_in_the_middle_keeps_a_prefix_and_counts_the_loss(tmp_path: Path, bag_bytes, circle) -> None:
    data, metadata = bag_bytes
    _, traj = circle
    run = read_bag(_copy(tmp_path, data[: len(data) // 2], metadata))
    kept = run.joint_states.stamp_ns.size
    assert not run.integrity.complete and run.integrity.method == "scan"
    assert 0 < kept < 2000
    assert run.integrity.lost["/cnc/joint_states"] == 2000 - kept
    assert_array_equal(run.joint_states.position_m, traj.position_m[:kept])
    assert "lost" in run.integrity.describe()


def test_cut_in_the_summary_recovers_everything_but_is_not_complete(tmp_path: Path, bag_bytes) -> None:
    data, metadata = bag_bytes
    run = read_bag(_copy(tmp_path, data[:-50], metadata))
    assert not run.integrity.complete
    assert run.integrity.lost == dict.fromkeys(run.integrity.found, 0)
    assert run.joint_states.stamp_ns.size == 2000


def test_without_metadata_the_loss_is_unknown(tmp_path: Path, bag_bytes) -> None:
    data, _ = bag_bytes
    run = read_bag(_copy(tmp_path, data[: len(data) // 2], None))
    assert not run.integrity.complete
    assert run.integrity.lost is None and run.integrity.expected_source == "unknown"
    assert "unknown" in run.integrity.describe()


def test_intact_file_without_metadata_is_complete_by_its_summary(tmp_path: Path, bag_bytes) -> None:
    data, _ = bag_bytes
    run = read_bag(_copy(tmp_path, data, None))
    assert run.integrity.complete and run.integrity.expected_source == "mcap summary"
    assert any("metadata.yaml is missing" in p for p in run.integrity.problems)


def _read_damaged(data: bytes, metadata: str | None) -> object:
    with tempfile.TemporaryDirectory() as tmp:
        try:
            return read_bag(_copy(Path(tmp), data, metadata))
        except BagError as err:
            return err


@SETTINGS
@given(fraction=st.floats(0.0, 1.0, exclude_max=True), with_metadata=st.booleans())
def test_any_cut_gives_bag_error_or_an_incomplete_prefix(bag_bytes, circle, fraction: float,
                                                         with_metadata: bool) -> None:
    data, metadata = bag_bytes
    _, traj = circle
    result = _read_damaged(data[: int(fraction * len(data))], metadata if with_metadata else None)
    if isinstance(result, BagError):
        assert "INCOMPLETE" in str(result)
        return
    integrity = result.integrity
    assert not integrity.complete and integrity.method == "scan"
    kept = result.joint_states.stamp_ns.size
    assert_array_equal(result.joint_states.position_m, traj.position_m[:kept])
    if with_metadata:
        assert integrity.lost["/cnc/joint_states"] == 2000 - kept
    else:
        assert integrity.lost is None or integrity.expected_source == "mcap summary"


@SETTINGS
@given(position=st.floats(0.0, 1.0, exclude_max=True), value=st.integers(0, 255))
def test_a_corrupt_byte_never_raises_anything_but_bag_error(bag_bytes, position: float, value: int) -> None:
    data, metadata = bag_bytes
    index = int(position * len(data))
    damaged = data[:index] + bytes([value]) + data[index + 1:]
    result = _read_damaged(damaged, metadata)
    assert isinstance(result, BagError) or result.joint_states.stamp_ns.size <= 2000


# --------------------------------------------------------------------------- typestore and columnar decoding
def test_custom_types_come_from_the_msg_files() -> None:
    store = project_typestore()
    assert (find_msg_dir() / "Reference.msg").is_file()
    assert "cnc_contour_interfaces/msg/PathSegment" in store.types
    assert "sensor_msgs/msg/JointState" in store.types


def test_msg_files_are_found_in_an_installed_prefix_first(tmp_path: Path) -> None:
    share = tmp_path / "prefix" / "share" / "cnc_contour_interfaces" / "msg"
    share.mkdir(parents=True)
    (share / "Reference.msg").write_text((find_msg_dir() / "Reference.msg").read_text())
    candidates = candidate_msg_dirs(f"{tmp_path / 'nowhere'}:{tmp_path / 'prefix'}")
    assert find_msg_dir(candidates) == share
    assert candidates[-1].parts[-2:] == ("cnc_contour_interfaces", "msg")
    with pytest.raises(ConfigError, match="message definitions not found; searched .*nowhere"):
        find_msg_dir(candidates[:1])


name_lists = st.lists(st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=6), max_size=4)


@SETTINGS
@given(st.lists(st.tuples(name_lists, st.text(max_size=5).filter(lambda s: "\x00" not in s),
                          st.integers(0, 2**31 - 1)), min_size=1, max_size=30))
def test_columnar_decoding_matches_rosbags(messages: list[tuple[list[str], str, int]]) -> None:
    store = project_typestore()
    types = store.types
    objects = [types["sensor_msgs/msg/JointState"](
        header=types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=7),
                                            frame_id=frame),
        name=names, position=np.arange(len(names), dtype=float) + sec, velocity=np.zeros(0),
        effort=np.full(len(names) % 2, 0.5)) for names, frame, sec in messages]
    raws = [bytes(store.serialize_cdr(m, "sensor_msgs/msg/JointState")) for m in objects]
    blocks = decode_columns(raws, "sensor_msgs/msg/JointState", store)
    assert sorted(np.concatenate([b.rows for b in blocks]).tolist()) == list(range(len(raws)))
    for block in blocks:
        for row, index in enumerate(block.rows):
            original = objects[index]
            assert block.strings["name"] == tuple(original.name)
            assert block.strings["header.frame_id"] == original.header.frame_id
            assert block.numbers["header.stamp.sec"][row] == original.header.stamp.sec
            assert_array_equal(block.numbers["position"][row], original.position)
            assert_array_equal(block.numbers["effort"][row], original.effort)


def test_columnar_decoding_refuses_nested_sequences_and_truncated_messages() -> None:
    store = project_typestore()
    with pytest.raises(ConfigError, match="segments"):
        decode_columns([b"\x00\x01\x00\x00" + bytes(64)], "cnc_contour_interfaces/msg/Path", store)
    with pytest.raises(BagError, match="ends inside a field"):
        decode_columns([b"\x00\x01\x00\x00\x01\x00"], "sensor_msgs/msg/JointState", store)


def test_a_flushed_bag_survives_its_writer_being_killed(tmp_path: Path) -> None:
    """After flush() the messages are in the file: a writer that never closes (killed) loses nothing flushed."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent(f"""
        import os, signal
        from cnc_tools.bagio.bag import BagWriter
        from cnc_tools.bagio.synthetic import joint_state
        import numpy as np
        w = BagWriter({str(tmp_path / 'bag')!r}, {{"/cnc/joint_states": "sensor_msgs/msg/JointState"}})
        for k in range(50):
            w.write_message("/cnc/joint_states", k * 10_000_000,
                            joint_state(k * 10_000_000, ["x"], np.array([k * 1e-3]), np.zeros(1)))
        w.flush()
        for k in range(50, 60):
            w.write_message("/cnc/joint_states", k * 10_000_000,
                            joint_state(k * 10_000_000, ["x"], np.array([k * 1e-3]), np.zeros(1)))
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, check=False)
    assert done.returncode == -9
    from cnc_tools.bagio.raw_bag import locate, read_raw

    raw, integrity = read_raw(locate(tmp_path / "bag"), lambda topic: True)
    assert not integrity.complete
    assert len(raw.data["/cnc/joint_states"]) == 50, "every flushed message is recovered, the unflushed 10 are lost"
