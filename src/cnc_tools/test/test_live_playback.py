"""Playback control of ``replay --live``: the clock and the schedule's seek, and a replay paused, sought and sped
up by a protocol client (foxglove's PlaybackControl capability, no browser) while the stream follows."""
from __future__ import annotations

import argparse
import functools
import math
import queue
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.bagio.bag import BagIntegrity
from cnc_tools.bagio.playback import PAUSED, PlaybackClock, PlaybackControl, PlaybackReport, PlaybackRequest
from cnc_tools.bagio.replay import RawMessage, Recording, ReplayConfig, ReplaySchedule
from cnc_tools.bagio.typestore import project_typestore
from cnc_tools.live.client import LiveClient, Received

MS = 1_000_000
JS = "sensor_msgs/msg/JointState"
_STAMP = struct.Struct("<iI")


# --------------------------------------------------------------------------- the clock and the schedule
def test_the_clock_runs_at_speed_over_rate_stands_while_paused_and_continues_from_a_seek() -> None:
    clock = PlaybackClock(2.0)
    assert clock.elapsed_s(5.0) == 0.0 and not clock.started
    clock.start(10.0)
    assert clock.elapsed_s(11.0) == 1.0 and clock.wall_wait_s(1.0) == 1.0  # speed = rate: wall time exactly
    clock.set(True, 4.0, 11.0)  # twice the configured rate
    assert clock.elapsed_s(12.0) == pytest.approx(3.0) and clock.wall_wait_s(1.0) == pytest.approx(0.5)
    clock.set(False, 4.0, 12.5)
    assert clock.elapsed_s(99.0) == pytest.approx(4.0) and clock.wall_wait_s(1.0) is None
    clock.seek(0.5, 100.0)
    clock.set(True, 2.0, 101.0)
    assert clock.elapsed_s(102.0) == pytest.approx(1.5)


@pytest.mark.parametrize("speed", [0.0, -1.0, 1e5, math.nan])
def test_a_speed_out_of_the_rate_bounds_is_refused_by_name_and_bound_and_changes_nothing(speed: float) -> None:
    clock = PlaybackClock(1.0)
    clock.start(0.0)
    with pytest.raises(ConfigError, match=r"replay\.rate must be"):
        clock.set(False, speed, 1.0)
    assert clock.playing and clock.speed == 1.0 and clock.elapsed_s(2.0) == 2.0


def test_an_asker_gets_its_answer_and_an_answer_given_too_late_goes_to_the_report() -> None:
    control = PlaybackControl((0, 10 * MS))
    late: list[PlaybackReport] = []
    control.report = late.append

    def replay() -> None:  # the replay's thread: take each request as it comes and answer it
        for _ in range(2):
            while not (requests := control.take()):
                time.sleep(0.001)
            control.answer(requests[0], PlaybackReport(PAUSED, 5 * MS, requests[0].speed, request_id="r"))

    thread = threading.Thread(target=replay)
    thread.start()
    answer = control.ask(PlaybackRequest(False, 2.0, request_id="r"), 10.0)
    assert answer == PlaybackReport(PAUSED, 5 * MS, 2.0, request_id="r") and late == []
    assert control.ask(PlaybackRequest(False, 3.0, request_id="r"), 0.0) is None  # gave up at once
    thread.join(10.0)
    assert [r.speed for r in late] == [3.0]


def _recording(times_ms: list[float]) -> Recording:
    messages = tuple(RawMessage("/a", round(t * MS), f"{t}".encode()) for t in times_ms)
    integrity = BagIntegrity(True, "index", {"/a": len(messages)}, {"/a": len(messages)}, "test")
    return Recording(Path("memory"), {"/a": JS}, messages, integrity)


def test_seek_goes_to_the_first_message_at_or_after_the_time_and_the_timeline_is_log_time() -> None:
    schedule = ReplaySchedule(_recording([5.0, 6.0, 7.0, 8.0]), ReplayConfig(rate=2.0, start_offset_s=1e-3))
    assert schedule.time_range_ns() == (6 * MS, 8 * MS)
    assert schedule.seek(round(6.5 * MS)) == pytest.approx(0.25e-3)  # 0.5 ms of log time in, at rate 2
    assert [m.data for m in schedule.step(0.5e-3)] == [b"7.0"]
    assert schedule.time_ns(0.5e-3) == 7 * MS and schedule.time_ns(10.0) == 8 * MS  # at most the last
    assert schedule.seek(0) == 0.0 and [m.data for m in schedule.step(1.0)] == [b"6.0", b"7.0", b"8.0"]


def test_a_looping_timeline_stays_within_one_pass() -> None:
    schedule = ReplaySchedule(_recording([0.0, 1.0, 2.0]), ReplayConfig(loop=True))
    assert schedule.time_ns(2.5e-3) == round(0.5 * MS)


@pytest.mark.nodes
def test_a_looping_replay_tells_the_viewer_when_it_starts_over(tmp_path: Path, synth: SimpleNamespace) -> None:
    from cnc_contour_control.testing import InProcessNode, wait_until
    from cnc_tools.nodes.replay_node import ReplayNode

    bag = synth.write_run_bag(tmp_path / "run", synth.circle_program(), synth.circle_trajectory(0.02, 0.0, n=40))
    control = PlaybackControl((0, 39 * MS))
    reports: list[PlaybackReport] = []
    control.report = reports.append
    with InProcessNode(functools.partial(ReplayNode, control=control), {"bag": str(bag), "loop": True}):
        wait_until(lambda: any(r.did_seek for r in reports), 30.0, "a report of the loop starting over")
    wrap = next(r for r in reports if r.did_seek)
    assert wrap.status == "playing" and 0 <= wrap.time_ns < 39 * MS and wrap.request_id == ""


def test_paused_without_live_is_a_usage_error_naming_both_options() -> None:
    from cnc_tools.cli.replay import configure, replay

    parser = argparse.ArgumentParser()
    configure(parser)
    with pytest.raises(ConfigError, match="--paused needs --live"):
        replay(parser.parse_args(["no-such-bag", "--paused"]))


# --------------------------------------------------------------------------- the command, driven by a viewer
@contextmanager
def _replay_live(bag: Path) -> Iterator[tuple[LiveClient, subprocess.Popen[bytes]]]:
    """``replay BAG --live --paused`` of the path and the joint states (the live node keeps up with 2000 ticks/s
    of them on a loaded machine, not with every topic) in its own process (any free port) and a client subscribed
    to joint states; the process is killed and the client closed however the test ends."""
    command = [sys.executable, "-m", "cnc_tools.cli.main", "replay", str(bag), "--live", "--live-port", "0",
               "--live-linger", "0", "--paused", "--topics", "/cnc/path", "/cnc/joint_states"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    lines: queue.Queue[bytes] = queue.Queue()
    threading.Thread(target=_read_lines, args=(process, lines), daemon=True).start()
    client: LiveClient | None = None
    try:
        url = _served_url(lines, process)
        client = LiveClient(url)
        client.wait_channels(["/cnc/joint_states"])
        client.subscribe(["/cnc/joint_states"])
        yield client, process
    finally:
        if client is not None:
            client.close()
        if process.poll() is None:
            process.kill()
        process.wait(timeout=10)


def _read_lines(process: subprocess.Popen[bytes], lines: queue.Queue[bytes]) -> None:
    for line in process.stdout or ():
        lines.put(line)


def _served_url(lines: queue.Queue[bytes], process: subprocess.Popen[bytes], timeout_s: float = 60.0) -> str:
    """The ``ws://`` address the command prints (``live: serving on ...``)."""
    seen: list[bytes] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=0.2)
        except queue.Empty:
            if process.poll() is not None:
                break
            continue
        seen.append(line)
        if line.startswith(b"live: serving on "):
            return line.split()[3].decode()
    raise AssertionError(f"replay --live printed no address: {b''.join(seen).decode()}")


def _stamps_ms(received: list[Received]) -> list[float]:
    """Header stamps of joint states, ms: the CDR's first fields after its 4-byte encapsulation (sec, nanosec)."""
    return [sec * 1e3 + nanosec / MS for sec, nanosec in (_STAMP.unpack_from(m.payload, 4) for m in received)]


def test_the_stamp_read_from_the_cdr_is_the_message_s(synth: SimpleNamespace) -> None:
    cdr = project_typestore().serialize_cdr(synth.joint_state(1_234_000_000, ["x"], [0.0], [0.0]), JS)
    assert _stamps_ms([Received("/cnc/joint_states", 0, 0, bytes(cdr))]) == [1234.0]


@pytest.mark.nodes
def test_a_viewer_plays_pauses_seeks_and_speeds_up_a_replay_and_the_stream_follows(
        tmp_path: Path, synth: SimpleNamespace) -> None:
    bag = synth.write_run_bag(tmp_path / "run", synth.circle_program(), synth.circle_trajectory(0.02, 0.0, n=2000))
    with _replay_live(bag) as (client, process):
        play = client.control_playback(True, 0.5, "play")
        assert (play.status, play.speed) == ("playing", 0.5)
        client.collect(bool, 30.0)  # the replay is ahead of what a (slow) client has read: pause at once
        pause = client.control_playback(False, 0.5, "pause")
        assert pause.status == "paused" and 0 < pause.time_ns < 2000 * MS
        last_ms = float(pause.time_ns // MS)  # the last tick published before the pause (ticks 1 ms apart)
        client.collect(lambda got: _stamps_ms(got[-1:])[0] >= last_ms, 30.0)  # the client reads behind the replay
        held = len(client.pending)
        client.poll(0.3)
        assert len(client.pending) == held, "messages arrived while paused"
        assert _stamps_ms(client.pending[-1:]) == [last_ms]

        seek = client.control_playback(False, 1.0, "seek", seek_ns=100 * MS)
        assert (seek.status, seek.time_ns, seek.did_seek) == ("paused", 100 * MS, True)
        refused = client.control_playback(True, 0.0, "bad")
        assert (refused.status, refused.time_ns, refused.speed) == ("paused", 100 * MS, 1.0)  # nothing changed
        reasons = [s["message"] for s in client.statuses]
        assert any("replay.rate must be in [0.001, 10000.0], got 0.0" in r for r in reasons), reasons
        assert len(client.pending) == held
        asked_at = time.monotonic()
        fast = client.control_playback(True, 2.0, "fast")
        assert (fast.status, fast.speed) == ("playing", 2.0)
        client.collect(lambda got: len(got) > held and _stamps_ms(got[-1:])[0] >= 500.0, 30.0)
        wall_s = time.monotonic() - asked_at
        after = _stamps_ms(client.pending[held:])
        assert after[0] == 100.0, "the stream did not continue from the time sought"
        assert after == [100.0 + k for k in range(len(after))], "ticks missing or out of order after the seek"
        assert wall_s >= 0.4 / 2.0 / 1.25, f"0.4 s of log time in {wall_s:.3f} s of wall time at speed 2"

        client.collect(lambda _: any(p.status == "ended" for p in client.playback), 30.0)
        assert process.wait(timeout=30) == 0
