"""Tier 1 and 2: stale Fast DDS shared-memory segments are found by their lock file and only this session's go."""
from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from cnc_contour_control.testing import wait_until
from cnc_tools.runs.dds import loopback_env
from cnc_tools.runs.shm import SHM_DIR, fast_dds_segments, is_stale, remove_stale_segments


def _segment(directory: Path, name: str) -> Path:
    segment = directory / f"fastrtps_{name}"
    segment.write_bytes(b"\0" * 64)
    segment.with_name(segment.name + "_el").touch()
    return segment


def test_only_the_sessions_own_unheld_segments_are_removed(tmp_path: Path) -> None:
    before = _segment(tmp_path, "before")
    present = fast_dds_segments(tmp_path)
    held, left, young = (_segment(tmp_path, name) for name in ("held", "left", "young"))
    (tmp_path / "fastrtps_port7411").touch()  # no lock file beside it: not a segment
    old = os.stat(left).st_mtime - 120.0
    for path in (held, left):
        os.utime(path.with_name(path.name + "_el"), (old, old))
    fd = os.open(held.with_name(held.name + "_el"), os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX)  # a live owner
    try:
        assert not is_stale(held) and is_stale(left) and is_stale(before)
        removed = remove_stale_segments(present, tmp_path)
    finally:
        os.close(fd)
    assert removed == [left]
    assert not left.exists() and not (tmp_path / "fastrtps_left_el").exists()
    assert before.exists() and held.exists() and young.exists() and (tmp_path / "fastrtps_port7411").exists()


@pytest.mark.nodes
def test_a_killed_participant_leaves_a_segment_that_is_found_stale() -> None:
    """Tier 2: a real participant killed by SIGKILL leaves its segment with nobody holding the lock."""
    present = fast_dds_segments()
    code = ("import rclpy, time; rclpy.init(); n = rclpy.create_node('shm_probe'); print('up', flush=True); "
            "time.sleep(60)")
    process = subprocess.Popen([sys.executable, "-c", code], env=loopback_env(), stdout=subprocess.PIPE, text=True)
    try:
        assert process.stdout is not None and process.stdout.readline().strip() == "up"
        maps = Path(f"/proc/{process.pid}/maps").read_text()
        mine = {segment for segment in fast_dds_segments() - present if str(segment) in maps}
        assert mine, "the participant made and mapped a shared-memory segment"
        assert not any(is_stale(segment) for segment in mine), "held while the participant lives"
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait()
    wait_until(lambda: all(is_stale(segment) for segment in mine), 10.0, "the killed owner's locks to drop")
    others = fast_dds_segments() - mine  # another worker's nodes may come and go meanwhile: not this test's
    removed = set(remove_stale_segments(others, SHM_DIR, min_age_s=0.0))
    # mine go; of the rest only what appeared after `others` was taken can go (another worker's node killed in
    # between leaves a stale segment of its own), never one present before
    assert mine <= removed and not (removed & others), (sorted(mine), sorted(removed))
    assert not (fast_dds_segments() & mine)
