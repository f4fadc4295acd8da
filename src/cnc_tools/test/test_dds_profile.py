"""Tier 2 (all but the heartbeat period, read from the file): the shipped Fast DDS profile is one Fast DDS itself
parses without a complaint, and it sends user data over shared memory.

A profile with one bad element is dropped whole by Fast DDS (only an
``XMLPARSER`` error on stderr says so), and with it the loopback binding:
a real participant is made under the runner's environment and its output read.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from cnc_tools.runs.dds import loopback_env, profile_path

NS = "{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}"
PARTICIPANT = """
import rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("profile_probe")
node.create_publisher(String, "profile_probe", 10)
node.destroy_node()
rclpy.shutdown()
print("participant made")
"""


def _made_under(profile: Path) -> subprocess.CompletedProcess[str]:
    """Make one participant with a publisher under ``profile`` (the runner's loopback environment otherwise)."""
    env = loopback_env({**os.environ, "FASTRTPS_DEFAULT_PROFILES_FILE": str(profile),
                        "FASTDDS_DEFAULT_PROFILES_FILE": str(profile)})
    return subprocess.run([sys.executable, "-c", PARTICIPANT], env=env, capture_output=True, text=True, timeout=60)


@pytest.mark.nodes
def test_fast_dds_parses_the_shipped_profile_without_an_error() -> None:
    done = _made_under(profile_path())
    output = done.stdout + done.stderr  # Fast DDS logs its errors to stdout
    assert done.returncode == 0 and "participant made" in done.stdout, output
    assert "XMLPARSER" not in output, output  # the parser's own errors; a transport's are another matter


@pytest.mark.nodes
def test_a_bad_element_is_what_the_check_above_would_see(tmp_path: Path) -> None:
    """The check can fail: the same profile with one misspelt element makes Fast DDS print an XMLPARSER error."""
    broken = tmp_path / "broken.xml"
    broken.write_text(profile_path().read_text().replace("heartbeatPeriod>", "heartbeatPeriodMs>"))
    done = _made_under(broken)
    assert "XMLPARSER" in done.stdout + done.stderr, done


def test_reliable_writers_repair_a_lost_last_sample_well_within_a_nodes_exit_wait() -> None:
    """The default writer's heartbeat period: a node waits 2 s for acknowledgements before it exits."""
    root = ET.parse(profile_path()).getroot()
    writers = [w for w in root.iter(f"{NS}data_writer") if w.get("is_default_profile") == "true"]
    assert len(writers) == 1, "one default data_writer profile"
    period = writers[0].find(f"{NS}times/{NS}heartbeatPeriod")
    assert period is not None
    period_s = int(period.findtext(f"{NS}sec")) + int(period.findtext(f"{NS}nanosec")) * 1e-9
    assert 0.0 < period_s <= 0.2, period_s


#: Counts the user data a ping-pong sends over loopback UDP (run in a network namespace of its own).
USER_DATA_OVER_UDP = Path(__file__).with_name("user_data_over_udp.py")
ROUND_TRIPS = 50


def _user_data_over_udp(profile: Path) -> dict[str, int]:
    """The DATA submessages of user writers that a Reference ping-pong of :data:`ROUND_TRIPS` round trips under
    ``profile`` sends over UDP, in a network namespace of its own (loopback only), so that no other process's
    traffic is seen; heartbeats, acknowledgements and discovery are not counted, so neither time nor load
    changes the figure (``user_data_over_udp.py``)."""
    env = loopback_env({**os.environ, "FASTRTPS_DEFAULT_PROFILES_FILE": str(profile),
                        "FASTDDS_DEFAULT_PROFILES_FILE": str(profile)})
    done = subprocess.run(["unshare", "--map-root-user", "--net", "sh", "-c", 'ip link set lo up && exec "$0" "$@"',
                           sys.executable, str(USER_DATA_OVER_UDP), str(ROUND_TRIPS)],
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


@pytest.mark.nodes
def test_user_data_goes_over_shared_memory_not_loopback_udp(tmp_path: Path) -> None:
    """A participant announces the default unicast locators its profile lists: a UDP-only list (as this profile
    had until 2026-11-27) sends every sample through the kernel's UDP stack although SHM is a transport."""
    udp_only = tmp_path / "udp_only.xml"
    udp_only.write_text(profile_path().read_text().replace(
        "      <builtin>",
        "      <defaultUnicastLocatorList>\n        <locator><udpv4><address>127.0.0.1</address></udpv4></locator>\n"
        "      </defaultUnicastLocatorList>\n      <builtin>", 1))
    over_udp = _user_data_over_udp(udp_only)  # the check can fail: two samples a round trip, none lost by us
    assert over_udp["user_data_submessages"] + over_udp["dropped"] >= 2 * ROUND_TRIPS, over_udp
    shipped = _user_data_over_udp(profile_path())
    assert shipped["rtps_datagrams"] > 0 and shipped["dropped"] == 0, shipped  # the capture saw the discovery
    assert shipped["user_data_submessages"] == 0, shipped
