"""Tier 2: the shipped Fast DDS profile is one Fast DDS itself parses without a complaint.

A profile with one bad element is dropped whole by Fast DDS (only an
``XMLPARSER`` error on stderr says so), and with it the loopback binding:
a real participant is made under the runner's environment and its output read.
"""
from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

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


def test_fast_dds_parses_the_shipped_profile_without_an_error() -> None:
    done = _made_under(profile_path())
    output = done.stdout + done.stderr  # Fast DDS logs its errors to stdout
    assert done.returncode == 0 and "participant made" in done.stdout, output
    assert "XMLPARSER" not in output, output  # the parser's own errors; a transport's are another matter


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
