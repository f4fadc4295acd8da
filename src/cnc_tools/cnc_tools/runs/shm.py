"""Fast DDS shared-memory segments that a killed node leaves behind in ``/dev/shm``.

Every participant's shared-memory transport makes a segment
(``fastrtps_<id>``, about 0.5 MB of RAM in a tmpfs) and a lock file beside it
(``fastrtps_<id>_el``) that its owner holds with ``flock`` while it lives. A
process that exits cleanly removes both; one killed by SIGKILL (the tests of
a node that dies, a runner's last resort) leaves them, and Fast DDS does not
clean them up later: a day of test runs here left 694 (366 MB). A segment is
stale when nothing holds its lock file.
"""
from __future__ import annotations

import fcntl
import os
import time
from collections.abc import Collection
from pathlib import Path

SHM_DIR = Path("/dev/shm")
#: Prefix of Fast DDS's segment files; the lock file adds this suffix.
SEGMENT_PREFIX, LOCK_SUFFIX = "fastrtps_", "_el"
#: A segment younger than this may belong to a participant that is still making it (lock file not yet held).
MIN_AGE_S = 5.0


def fast_dds_segments(directory: Path = SHM_DIR) -> set[Path]:
    """The Fast DDS segments in ``directory`` (the files with a lock file beside them)."""
    if not directory.is_dir():
        return set()
    return {lock.with_name(lock.name[:-len(LOCK_SUFFIX)])
            for lock in directory.glob(f"{SEGMENT_PREFIX}*{LOCK_SUFFIX}")}


def is_stale(segment: Path) -> bool:
    """True when no process holds ``segment``'s lock file (its owner is gone)."""
    try:
        fd = os.open(segment.with_name(segment.name + LOCK_SUFFIX), os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return True
    finally:
        os.close(fd)


def remove_stale_segments(present_before: Collection[Path], directory: Path = SHM_DIR,
                          min_age_s: float = MIN_AGE_S) -> list[Path]:
    """Remove the stale segments (and lock files) made since ``present_before`` was taken; return them.

    Only segments that were not there before (this session's), older than ``min_age_s`` and with nobody
    holding their lock: a participant of another session is never touched.
    """
    now = time.time()
    removed = []
    for segment in sorted(fast_dds_segments(directory) - set(present_before)):
        lock = segment.with_name(segment.name + LOCK_SUFFIX)
        try:
            young = now - lock.stat().st_mtime < min_age_s
        except OSError:
            continue
        if young or not is_stale(segment):
            continue
        for path in (segment, lock):
            path.unlink(missing_ok=True)
        removed.append(segment)
    return removed
