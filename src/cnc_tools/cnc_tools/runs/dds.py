"""Keep DDS on this machine: the environment every process of a run gets.

Policy (same as ``scripts/setup.sh``): localhost discovery, the suite's
loopback-only Fast DDS profile unless the user set their own, Fast DDS as the
middleware, and a random domain unless one is set.
"""
from __future__ import annotations

import os
import random
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
    profile = env.get("FASTRTPS_DEFAULT_PROFILES_FILE") or env.get("FASTDDS_DEFAULT_PROFILES_FILE") or str(profile_path())
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
