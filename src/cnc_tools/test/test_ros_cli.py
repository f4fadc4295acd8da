"""Tier 2: ``cnc-contour ros`` against a running graph: plant, servos and an action-mode interpolator in-process
(named and parametrised as the runner starts paper 000's circle), each subcommand as a user types it."""
from __future__ import annotations

import re
import sys
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest
from sensor_msgs.msg import JointState

from cnc_contour_control.testing import WAIT_FLOOR_S, TopicProbe
from cnc_tools.cli import send_program
from cnc_tools.cli.main import main as cli
from cnc_tools.runs.scenario import load_scenario
from cnc_tools.testing import own_domain, start_graph_in_process

pytestmark = pytest.mark.nodes
SCENARIO = Path(__file__).resolve().parents[3] / "scenarios" / "paper000_circle_high.yaml"


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """The lockstep graph, ticking for as long as the module's tests run, and the tools, in a domain of the
    module's own (:func:`cnc_tools.testing.own_domain`)."""
    with ExitStack() as stack, own_domain():
        start_graph_in_process(stack, load_scenario(SCENARIO, {}), tmp_path_factory.mktemp("graph"))
        with TopicProbe({"/cnc/joint_states": JointState}) as probe:  # running: the plant ticks
            probe.wait_for(lambda: len(probe.received("/cnc/joint_states")) > 10, 30.0, "the graph's ticks")
        yield


#: How long a tool waits for the graph here: a new process's reader matches in 2-3 s on a quiet machine, longer under
#: load (the tools' own default is 5 s; action send's 10 s). The wait ends when the answer comes.
WAIT_S = f"{WAIT_FLOOR_S:g}"


#: The subcommands that look the graph up (each takes --wait-s).
LOOKUPS = {"nodes", "topics", "echo", "hz", "param", "lifecycle", "action"}


def ros(capsys: pytest.CaptureFixture[str], *words: str) -> tuple[int, str]:
    wait = ["--wait-s", WAIT_S] if words[0] in LOOKUPS and "--wait-s" not in words else []
    code = cli(["ros", *words, *wait])
    captured = capsys.readouterr()
    sys.stderr.write(captured.err)  # the tool's error line, in the report of a test that fails
    return code, captured.out


def test_nodes_topics_echo_and_hz_read_the_running_graph(graph: None, capsys: pytest.CaptureFixture[str]) -> None:
    code, out = ros(capsys, "nodes", "--settle-s", "3", "--wait-s", "10")  # the default settles in 2 s: see ros.py
    assert code == 0 and {"/cnc/plant", "/cnc/interpolator", "/cnc/servo_x", "/cnc/servo_y"} <= set(out.split())
    assert "_cnc_contour_ros" not in out, "the tool's own node is hidden"
    code, out = ros(capsys, "topics", "-t", "--settle-s", "3", "--wait-s", "10")
    assert code == 0 and "/cnc/joint_states [sensor_msgs/msg/JointState]" in out.splitlines(), out
    code, out = ros(capsys, "echo", "/cnc/joint_states", "--once", "--wait-s", WAIT_S)
    assert code == 0 and out.count("---") == 1 and "name:\n- x\n- y\n" in out, out
    code, out = ros(capsys, "echo", "/cnc/reference", "--csv", "--count", "3", "--wait-s", WAIT_S)
    rows = out.splitlines()
    assert code == 0 and len(rows) == 4 and rows[0].startswith("header.stamp.sec,header.stamp.nanosec,"), out
    assert "position_m.0" in rows[0].split(",") and all(len(r.split(",")) == len(rows[0].split(",")) for r in rows)
    code, out = ros(capsys, "hz", "/cnc/joint_states", "--duration-s", "1.5", "--wait-s", WAIT_S)
    rates = [float(r) for r in re.findall(r"average rate: ([0-9.]+) Hz", out)]
    assert code == 0 and rates and rates[-1] > 10.0, out
    assert cli(["ros", "echo", "/cnc/no_such_topic", "--once", "--wait-s", "0.5"]) == 2
    assert "no topic /cnc/no_such_topic in the graph within --wait-s 0.5 s" in capsys.readouterr().err


def test_param_get_set_describe_a_servo_gain(graph: None, capsys: pytest.CaptureFixture[str]) -> None:
    assert ros(capsys, "param", "get", "/cnc/servo_x", "gains.kp") == (0, "gains.kp: 2.4\n")
    assert ros(capsys, "param", "set", "/cnc/servo_x", "gains.kp", "3.0") == (0, "/cnc/servo_x gains.kp: set\n")
    assert ros(capsys, "param", "get", "/cnc/servo_x", "gains.kp") == (0, "gains.kp: 3.0\n")
    code, out = ros(capsys, "param", "describe", "/cnc/servo_x", "gains.kp")
    assert code == 0 and "  type: double" in out and "  read_only: false" in out, out
    code, out = ros(capsys, "param", "set", "/cnc/servo_x", "axis", "y")
    assert code == 1 and out.startswith("/cnc/servo_x axis: refused: "), out


def test_action_send_prints_feedback_and_ctrl_c_cancels_the_goal(graph: None, tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str],
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    part = tmp_path / "part.ngc"
    part.write_text("G1 X1 F1200\n")
    code, out = ros(capsys, "action", "send", str(part))
    assert code == 0 and "part: completed" in out, out
    long_part = tmp_path / "long.ngc"
    long_part.write_text("G1 X0 F1200\nG1 X30 F600\n")

    def ctrl_c(self: Any, msg: Any) -> None:  # the user presses Ctrl-C once, at the first feedback
        if not getattr(self, "pressed", False):
            self.pressed = True
            raise KeyboardInterrupt

    monkeypatch.setattr(send_program.FeedbackPrinter, "__call__", ctrl_c)
    code, out = ros(capsys, "action", "send", str(long_part))
    assert code == 130 and out.startswith("interrupted: long: canceled at "), out


def test_lifecycle_get_and_set_a_servo_last(graph: None, capsys: pytest.CaptureFixture[str]) -> None:
    """Last in the module: the machine watch takes the re-enabled servo's state from its next status report."""
    assert ros(capsys, "lifecycle", "get", "/cnc/servo_y") == (0, "/cnc/servo_y: active\n")
    assert ros(capsys, "lifecycle", "set", "/cnc/servo_y", "configure") == (
        1, "/cnc/servo_y configure: refused (its log and /diagnostics give the reason)\n")
    assert ros(capsys, "lifecycle", "set", "/cnc/servo_y", "deactivate") == (0, "/cnc/servo_y: inactive\n")
    assert ros(capsys, "lifecycle", "set", "/cnc/servo_y", "activate") == (0, "/cnc/servo_y: active\n")

