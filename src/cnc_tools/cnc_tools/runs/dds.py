"""Keep DDS on this machine: the environment every process of a run gets.

Policy (same as ``scripts/setup.sh``): localhost discovery, the suite's
loopback-only Fast DDS profile unless the user set their own, Fast DDS as the
middleware, and a random domain unless one is set. A test session claims a
domain that no other session on this host holds (:func:`claim_free_domain_id`).
"""
from __future__ import annotations

import contextlib
import fcntl
import os
import random
import tempfile
from collections.abc import Mapping, MutableMapping
from pathlib import Path

PROFILE_NAME = "fastdds_localhost.xml"


def profile_path() -> Path:
    """The shipped loopback-only profile: installed share dir, else the source tree."""
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        candidate = Path(prefix) / "share" / "cnc_tools" / "config" / PROFILE_NAME
        if prefix and candidate.is_file():
            return candidate
    return Path(__file__).resolve().parents[1] / "config" / PROFILE_NAME


def loopback_env(base: Mapping[str, str] | None = None, domain_id: int | None = None) -> dict[str, str]:
    """A copy of ``base`` (default: os.environ) with the loopback DDS policy applied."""
    env = dict(os.environ if base is None else base)
    apply_loopback_policy(env, domain_id)
    return env


def apply_loopback_policy(env: MutableMapping[str, str], domain_id: int | None = None) -> None:
    """Set the loopback DDS policy in ``env`` in place."""
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    profile = (env.get("FASTRTPS_DEFAULT_PROFILES_FILE") or env.get("FASTDDS_DEFAULT_PROFILES_FILE")
               or str(profile_path()))
    env["FASTRTPS_DEFAULT_PROFILES_FILE"] = profile
    env["FASTDDS_DEFAULT_PROFILES_FILE"] = profile
    if domain_id is not None:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    else:
        env.setdefault("ROS_DOMAIN_ID", str(random_domain_id()))


#: Highest domain we pick: its RTPS ports (7400 + 250·d + ...) stay below Linux's
#: ephemeral port range (32768 and up), so no socket bound to port 0 can take them.
MAX_RANDOM_DOMAIN_ID = 100


def random_domain_id() -> int:
    """A domain in 1..100 (ROS 2 advises 0..101 on Linux for the reason above)."""
    return random.SystemRandom().randint(1, MAX_RANDOM_DOMAIN_ID)


#: Where processes of this host claim a domain of their own (a lock file per domain; ``CNC_DOMAIN_LOCK_DIR``
#: overrides it).
DOMAIN_LOCK_DIR = Path(tempfile.gettempdir()) / "cnc_contour_domains"


class DomainClaim:
    """A ROS domain that no other claimant on this host holds while this claim is open.

    The claim is an ``flock`` on ``<lock dir>/<domain>.lock``: the kernel drops it when the process ends,
    however it ends, so a crashed test session leaves no stale claim. Only claimants are kept apart (every
    test session and its xdist workers); a ROS process that claims nothing may still join the domain.
    """

    def __init__(self, domain_id: int, fd: int) -> None:
        self.domain_id, self._fd = domain_id, fd

    def release(self) -> None:
        """Give the domain back (closing the lock file drops the flock)."""
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


def _open_lock(path: Path) -> int:
    """Open (or make) a lock file read-only: flock needs no more, so another user's file serves as well.

    O_CREAT only when it is missing: Linux's ``protected_regular`` refuses O_CREAT on another user's file in
    a sticky directory even where it exists.
    """
    try:
        return os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        pass
    try:
        return os.open(path, os.O_RDONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:  # another claimant made it meanwhile
        return os.open(path, os.O_RDONLY)


def _try_claim(lock_dir: Path, domain_id: int) -> DomainClaim | None:
    try:
        fd = _open_lock(lock_dir / f"{domain_id}.lock")
    except PermissionError:  # a file we may not read: not ours to claim
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    return DomainClaim(domain_id, fd)


def claim_free_domain_id(lock_dir: Path | None = None) -> DomainClaim:
    """Claim a domain in 1..100 that no other claimant holds, trying them in random order.

    Raises
    ------
    RuntimeError
        All 100 domains are claimed (names the lock directory), or the directory cannot be made.
    """
    where = lock_dir or Path(os.environ.get("CNC_DOMAIN_LOCK_DIR") or DOMAIN_LOCK_DIR)
    try:
        where.mkdir(parents=True, exist_ok=True)
        with contextlib.suppress(OSError):  # sticky and open to all, like /tmp: another user's sessions claim too
            where.chmod(0o1777)
        ids = list(range(1, MAX_RANDOM_DOMAIN_ID + 1))
        random.SystemRandom().shuffle(ids)
        for domain_id in ids:
            claim = _try_claim(where, domain_id)
            if claim is not None:
                return claim
    except OSError as err:
        raise RuntimeError(f"cannot claim a ROS domain in {where}: {err}") from err
    raise RuntimeError(f"all {MAX_RANDOM_DOMAIN_ID} ROS domains are claimed by live processes ({where})")
