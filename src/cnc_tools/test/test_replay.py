"""Replay: log-time order from intact and salvaged bags, the schedule, and real round trips over DDS."""
from __future__ import annotations

import math
import re
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader

from cnc_contour_control.core.errors import BagError, ConfigError
from cnc_contour_control.testing import wait_until
from cnc_tools.bagio.bag import PATH_TYPE, BagIntegrity, BagWriter
from cnc_tools.bagio.replay import (
    RawMessage,
    Recording,
    ReplayConfig,
    ReplaySchedule,
    load_recording,
    skip_empty,
)
from cnc_tools.bagio.typestore import project_typestore

JS, CLOCK = "sensor_msgs/msg/JointState", "rosgraph_msgs/msg/Clock"
MS = 1_000_000


# --------------------------------------------------------------------------- helpers
def _small_run(tmp_path: Path, synth, n: int = 40) -> Path:
    """A synthetic run: path, joint_states, reference, /clock and two command topics, n ticks 1 ms apart."""
    return synth.write_run_bag(tmp_path / "run", synth.circle_program(), synth.circle_trajectory(0.02, 0.0, n=n))


def _cut(bag: Path, keep: float, tmp_path: Path) -> Path:
    """A copy of ``bag`` whose .mcap keeps the first ``keep`` fraction of its bytes (metadata.yaml intact)."""
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    data = (bag / f"{bag.name}.mcap").read_bytes()
    (damaged / f"{bag.name}.mcap").write_bytes(data[: int(keep * len(data))])
    metadata = (bag / "metadata.yaml").read_text()
    (damaged / "metadata.yaml").write_text(metadata)
    return damaged


def _recorded(bag: Path) -> dict[str, list[bytes]]:
    """Each topic's raw messages in recorded order, read by rosbags alone (the reference for byte identity)."""
    with AnyReader([bag], default_typestore=project_typestore()) as reader:
        by_topic: dict[str, list[bytes]] = {c.topic: [] for c in reader.connections}
        for conn, _, data in reader.messages():
            by_topic[conn.topic].append(bytes(data))
    return by_topic


def _recording(log_times_ms: Mapping[str, list[float]], types: Mapping[str, str] | None = None) -> Recording:
    """A recording built in memory: each message's data is ``topic@ms``."""
    messages = [RawMessage(topic, round(t * MS), f"{topic}@{t}".encode())
                for topic, times in log_times_ms.items() for t in times]
    messages.sort(key=lambda m: m.log_time_ns)
    topics = dict(types or dict.fromkeys(log_times_ms, JS))
    counts = {t: len(v) for t, v in log_times_ms.items()}
    return Recording(Path("memory"), topics, tuple(messages), BagIntegrity(True, "index", counts, counts, "test"))


def _names(messages: list[RawMessage]) -> list[str]:
    return [m.data.decode() for m in messages]


# --------------------------------------------------------------------------- reading in log-time order
@pytest.mark.parametrize("damaged", [False, True], ids=["index", "salvage-scan"])
def test_messages_come_in_log_time_order_ties_in_file_order(tmp_path: Path, damaged: bool) -> None:
    written = [("/a", 20, b"a20"), ("/b", 10, b"b10"), ("/a", 10, b"a10"), ("/b", 20, b"b20"), ("/a", 30, b"a30")]
    with BagWriter(tmp_path / "ties", {"/a": JS, "/b": CLOCK}) as writer:
        for topic, log_time_ns, data in written:
            writer.write(topic, log_time_ns, data)
    bag = tmp_path / "ties"
    if damaged:
        mcap = bag / "ties.mcap"
        mcap.write_bytes(mcap.read_bytes()[:-50])  # the summary is cut: the index is unusable
    recording = load_recording(bag)
    assert recording.integrity.method == ("scan" if damaged else "index")
    assert [m.data for m in recording.messages] == [b"b10", b"a10", b"a20", b"b20", b"a30"]
    assert [m.log_time_ns for m in recording.messages] == [10, 10, 20, 20, 30]
    assert recording.topics == {"/a": JS, "/b": CLOCK}


def test_topics_filter_and_an_unknown_topic_named_with_the_bag_s_topics(tmp_path: Path, synth) -> None:
    bag = _small_run(tmp_path, synth, n=5)
    recording = load_recording(bag, ["/clock", "/cnc/path"])
    assert recording.counts() == {"/clock": 5, "/cnc/path": 1}
    assert recording.latched_topics == {"/cnc/path"}
    with pytest.raises(BagError, match=r"has no topics \['/cnc/nope'\]; it has \['/clock', '/cnc/joint_states'"):
        load_recording(bag, ["/clock", "/cnc/nope"])


def test_a_missing_bag_is_a_bag_error_naming_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from cnc_tools.cli.main import main

    with pytest.raises(BagError, match=f"bag {tmp_path / 'nothing'} does not exist"):
        load_recording(tmp_path / "nothing")
    assert main(["replay", str(tmp_path / "nothing")]) == 2
    assert f"cnc-contour replay: error: bag {tmp_path / 'nothing'} does not exist" in capsys.readouterr().err


def test_a_truncated_bag_gives_its_prefix_and_counts_the_loss(tmp_path: Path, synth) -> None:
    bag = _small_run(tmp_path, synth)
    recorded = _recorded(bag)
    recording = load_recording(_cut(bag, 0.5, tmp_path))
    integrity = recording.integrity
    assert not integrity.complete and integrity.method == "scan"
    kept = recording.counts()
    assert 0 < sum(kept.values()) < sum(len(v) for v in recorded.values())
    for topic, data in recorded.items():
        assert [m.data for m in recording.messages if m.topic == topic] == data[: kept.get(topic, 0)]
        assert integrity.lost[topic] == len(data) - kept.get(topic, 0)
    assert "lost" in recording.describe()


# --------------------------------------------------------------------------- the schedule
def _due_times(schedule: ReplaySchedule, count: int) -> list[float]:
    times = []
    for _ in range(count):
        times.append(schedule.due_s())
        schedule.step(times[-1], limit=1)
    return times


@pytest.mark.parametrize("rate", [0.5, 1.0, 4.0])
def test_log_time_maps_to_wall_time_divided_by_rate(rate: float) -> None:
    schedule = ReplaySchedule(_recording({"/a": [0.0, 1.0, 3.0], "/b": [2.0]}), ReplayConfig(rate=rate))
    assert schedule.due_s() == 0.0
    assert schedule.step(-1e-9) == []
    assert _due_times(schedule, 4) == pytest.approx([t * 1e-3 / rate for t in (0.0, 1.0, 2.0, 3.0)])
    assert schedule.done and schedule.due_s() is None and schedule.wait_s(1.0) is None


def test_step_returns_everything_due_in_order_and_measures_lateness() -> None:
    schedule = ReplaySchedule(_recording({"/a": [0.0, 1.0, 3.0], "/b": [2.0]}), ReplayConfig())
    assert _names(schedule.step(2.5e-3)) == ["/a@0.0", "/a@1.0", "/b@2.0"]
    assert schedule.max_late_s == pytest.approx(2.5e-3)
    assert schedule.wait_s(2.5e-3) == pytest.approx(0.5e-3)
    assert _names(schedule.step(10.0, limit=5)) == ["/a@3.0"]
    assert schedule.published == 4 and schedule.done


def test_start_offset_skips_earlier_messages_but_keeps_the_last_latched_one() -> None:
    recording = _recording({"/cnc/path": [0.0, 1.0], "/a": [0.0, 1.0, 2.0, 3.0]}, {"/cnc/path": PATH_TYPE, "/a": JS})
    schedule = ReplaySchedule(recording, ReplayConfig(start_offset_s=2e-3))
    assert _names(schedule.step(0.0)) == ["/cnc/path@1.0", "/a@2.0"]
    assert schedule.wait_s(0.0) == pytest.approx(1e-3)
    with pytest.raises(ConfigError, match=r"start_offset_s must be <= 0\.003"):
        ReplaySchedule(recording, ReplayConfig(start_offset_s=4e-3))


def test_loop_starts_over_shifted_by_one_pass() -> None:
    schedule = ReplaySchedule(_recording({"/a": [0.0, 1.0, 2.0]}), ReplayConfig(rate=2.0, loop=True))
    assert schedule.pass_s == pytest.approx(1e-3)
    assert _due_times(schedule, 7) == pytest.approx([0.0, 0.5e-3, 1e-3, 1e-3, 1.5e-3, 2e-3, 2e-3])
    assert not schedule.done and schedule.passes == 2
    schedule.reset()
    assert schedule.due_s() == 0.0 and schedule.published == 0


def test_long_empty_stretches_are_skipped_like_system_time_diagnostics() -> None:
    # Lockstep topics in simulation time from 0, one diagnostic in system time (decades later).
    recording = _recording({"/a": [0.0, 1.0, 2.0], "/diagnostics": [1.8e12]})
    schedule = ReplaySchedule(recording, ReplayConfig())
    assert _due_times(schedule, 4) == pytest.approx([0.0, 1e-3, 2e-3, 2e-3])
    assert schedule.skipped_s == pytest.approx(1.8e9 - 2e-3)
    kept = ReplaySchedule(recording, ReplayConfig(skip_empty_s=0.0))
    assert kept.pass_s == pytest.approx(1.8e9)


@pytest.mark.parametrize("offsets, threshold, expected, skipped", [
    ([0, 5, 100, 105], 10, [0, 5, 5, 10], 95),
    ([0, 5, 100, 105], 0, [0, 5, 100, 105], 0),
    ([0, 10, 20], 10, [0, 10, 20], 0),
    ([], 10, [], 0),
])
def test_skip_empty_cuts_only_gaps_longer_than_the_threshold(offsets: list[int], threshold: int,
                                                             expected: list[int], skipped: int) -> None:
    assert skip_empty(offsets, threshold) == (expected, skipped)


@pytest.mark.parametrize("key, value, message", [
    ("rate", 0.0, "replay.rate must be in [0.001, 10000.0], got 0.0"),
    ("rate", 2e4, "replay.rate must be in [0.001, 10000.0], got 20000.0"),
    ("rate", math.nan, "replay.rate must be finite"),
    ("start_offset_s", -1.0, "replay.start_offset_s must be in [0.0, 1000000000000.0], got -1.0"),
    ("skip_empty_s", -0.5, "replay.skip_empty_s must be in [0.0, 1000000000000.0], got -0.5"),
    ("topics", ("/a", ""), "replay.topics must be non-empty topic names"),
])
def test_config_refuses_bad_values_by_name(key: str, value: object, message: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(message)):
        ReplayConfig(**{key: value})


# --------------------------------------------------------------------------- the node over DDS
def _raw_probe(topics: Mapping[str, str]):
    """A TopicProbe with a raw subscription per replayed topic (bytes, as published) and /diagnostics."""
    from diagnostic_msgs.msg import DiagnosticArray

    from cnc_contour_control.nodes.common import LATCHED_QOS, LOCKSTEP_QOS
    from cnc_contour_control.testing import TopicProbe
    from cnc_tools.nodes.replay_node import message_class

    probe = TopicProbe({"/diagnostics": DiagnosticArray}, name="replay_probe")
    for topic, type_name in topics.items():
        qos = LATCHED_QOS if type_name == PATH_TYPE else LOCKSTEP_QOS
        probe.node.create_subscription(message_class(type_name), topic, probe.messages[topic].append, qos, raw=True)
    return probe


def _final_status(probe) -> object | None:
    """The replay node's end-of-replay diagnostic, once received."""
    for array in probe.received("/diagnostics"):
        for status in array.status:
            if status.name == "/cnc/replay" and status.message.startswith("replay finished"):
                return status
    return None



def _wait_for_all(probe, expected: Mapping[str, int], timeout_s: float = 30.0) -> None:
    probe.wait_for(lambda: all(len(probe.received(t)) >= n for t, n in expected.items()), timeout_s,
                   f"replayed messages {dict(expected)}")
    probe.wait_for(lambda: _final_status(probe) is not None, 10.0, "the replay's final diagnostic")


@pytest.mark.nodes
def test_node_replays_every_message_byte_identical_and_in_order(tmp_path: Path, synth) -> None:
    from diagnostic_msgs.msg import DiagnosticStatus

    from cnc_contour_control.testing import InProcessNode
    from cnc_tools.nodes.replay_node import ReplayNode

    bag = _small_run(tmp_path, synth)
    recorded = _recorded(bag)
    params = {"bag": str(bag), "rate": 20.0, "min_subscribers": 1}
    with _raw_probe(load_recording(bag).topics) as probe, InProcessNode(ReplayNode, params) as replay:
        _wait_for_all(probe, {t: len(v) for t, v in recorded.items()})
        assert replay.node.finished and replay.node.fault_message is None
        received = {topic: [bytes(b) for b in probe.received(topic)] for topic in recorded}
        status = _final_status(probe)
    assert received == recorded
    assert sum(map(len, recorded.values())) == 1 + 5 * 40
    values = {kv.key: kv.value for kv in status.values}
    assert status.level == DiagnosticStatus.OK and values["published"] == "201" and values["lost"] == "0"


@pytest.mark.nodes
def test_node_replays_the_salvaged_prefix_of_a_truncated_bag_and_reports_the_loss(tmp_path: Path, synth) -> None:
    from diagnostic_msgs.msg import DiagnosticStatus

    from cnc_contour_control.testing import InProcessNode
    from cnc_tools.nodes.replay_node import ReplayNode

    bag = _small_run(tmp_path, synth)
    recorded = _recorded(bag)
    damaged = _cut(bag, 0.5, tmp_path)
    recording = load_recording(damaged)
    kept = {t: recording.counts().get(t, 0) for t in recorded}
    lost = sum(len(v) for v in recorded.values()) - sum(kept.values())
    assert lost > 0
    with _raw_probe(recording.topics) as probe, InProcessNode(ReplayNode, {"bag": str(damaged), "rate": 20.0,
                                                                           "min_subscribers": 1}):
        _wait_for_all(probe, {t: n for t, n in kept.items() if t in recording.topics})
        received = {topic: [bytes(b) for b in probe.received(topic)] for topic in recorded}
        status = _final_status(probe)
    assert received == {topic: data[: kept[topic]] for topic, data in recorded.items()}
    values = {kv.key: kv.value for kv in status.values}
    assert status.level == DiagnosticStatus.WARN and values["lost"] == str(lost)
    assert values["published"] == str(sum(kept.values()))
    assert f"{lost} messages lost" in status.message


@pytest.mark.nodes
def test_the_command_replays_a_bag_in_its_own_process_and_exits(tmp_path: Path, synth) -> None:
    bag = _small_run(tmp_path, synth, n=10)
    recorded = _recorded(bag)
    command = [sys.executable, "-m", "cnc_tools.cli.main", "replay", str(bag), "--rate", "20",
               "--wait-for-subscribers", "1",
               "--topics", "/cnc/path", "/cnc/joint_states"]
    with _raw_probe({"/cnc/path": PATH_TYPE, "/cnc/joint_states": JS}) as probe:
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            _wait_for_all(probe, {"/cnc/path": 1, "/cnc/joint_states": 10})
            output, _ = process.communicate(timeout=30)
        finally:
            if process.poll() is None:
                process.kill()
                process.wait(timeout=10)
        received = {topic: [bytes(b) for b in probe.received(topic)] for topic in ("/cnc/path", "/cnc/joint_states")}
    assert process.returncode == 0, output.decode()
    assert received == {t: recorded[t] for t in received}
    assert b"replaying 11 messages on 2 topics" in output


@pytest.mark.nodes
def test_replaying_into_the_recorder_records_the_same_bag(tmp_path: Path, synth) -> None:
    from cnc_contour_control.testing import InProcessNode
    from cnc_tools.nodes.recorder_node import RecorderNode
    from cnc_tools.nodes.replay_node import ReplayNode

    bag = _small_run(tmp_path, synth)
    recorded = _recorded(bag)
    expected = {t: len(v) for t, v in recorded.items()}
    copy = tmp_path / "rerecorded"
    with InProcessNode(RecorderNode, {"output": str(copy), "axes": ["x", "y"]}) as recorder, \
            InProcessNode(ReplayNode, {"bag": str(bag), "rate": 20.0, "min_subscribers": 1}):

        def holds_everything() -> bool:
            counts = recorder.node.writer.message_counts
            return all(counts.get(t, 0) >= n for t, n in expected.items())

        wait_until(holds_everything, 30.0, f"the recorder to hold {expected}")
    rerecorded = _recorded(copy)  # the recorder closed its bag when its node was destroyed
    assert {t: rerecorded[t] for t in recorded} == recorded


# --------------------------------------------------------------------------- waiting for readers (issue 22)
def test_the_command_awaits_the_chosen_topics_else_all_but_the_clock_and_diagnostics(tmp_path: Path, synth) -> None:
    from cnc_tools.cli.replay import awaited_topics

    recording = load_recording(_small_run(tmp_path, synth))
    assert "/clock" in recording.topics
    assert awaited_topics(recording, ()) == sorted(t for t in recording.topics if t != "/clock")
    assert awaited_topics(recording, ("/clock", "/cnc/path")) == ["/clock", "/cnc/path"]


def _replay_command(bag: Path, *options: str) -> list[str]:
    return [sys.executable, "-m", "cnc_tools.cli.main", "replay", str(bag), "--rate", "20", *options]


@pytest.mark.nodes
def test_waiting_for_readers_that_never_come_says_for_whom_and_gives_up_at_the_timeout(tmp_path: Path, synth) -> None:
    """Before, without --topics it waited silently and for ever (for readers of /clock too)."""
    from cnc_contour_control.nodes.common import EXIT_FAULT
    from cnc_tools.runs.dds import claim_free_domain_id, loopback_env

    bag = _small_run(tmp_path, synth, n=10)
    domain = claim_free_domain_id()  # a domain of its own: no reader of /cnc/... from anyone else's test
    try:
        result = subprocess.run(_replay_command(bag, "--wait-for-subscribers", "1", "--wait-timeout", "1.5"),
                                capture_output=True, text=True, timeout=60,
                                env=loopback_env(domain_id=domain.domain_id))
    finally:
        domain.release()
    output = result.stdout + result.stderr
    assert result.returncode == EXIT_FAULT, output
    awaited = ", ".join(sorted(t for t in load_recording(bag).topics if t != "/clock"))
    assert f"waiting up to 1.5 s for 1 reader(s) of each of {awaited}\n" in result.stdout, output
    assert "no 1 reader(s) within wait_timeout_s = 1.5 s on /cnc/joint_states (0 of 1)" in output, output


@pytest.mark.nodes
def test_without_topics_it_starts_once_the_graphs_topics_have_readers_and_no_one_reads_the_clock(
        tmp_path: Path, synth) -> None:
    bag = _small_run(tmp_path, synth, n=10)
    recorded = _recorded(bag)
    read = {t: ty for t, ty in load_recording(bag).topics.items() if t != "/clock"}
    with _raw_probe(read) as probe:
        process = subprocess.Popen(_replay_command(bag, "--wait-for-subscribers", "1"), stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, start_new_session=True)
        try:
            _wait_for_all(probe, {t: len(recorded[t]) for t in read})
            output, _ = process.communicate(timeout=30)
        finally:
            if process.poll() is None:
                process.kill()
                process.wait(timeout=10)
        received = {topic: len(probe.received(topic)) for topic in read}
    assert process.returncode == 0, output.decode()
    assert received == {t: len(recorded[t]) for t in read}
    assert b"waiting up to 30 s for 1 reader(s) of each of /cnc/joint_states" in output
