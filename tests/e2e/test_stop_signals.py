"""Tier 3: a node stopped by SIGINT or SIGTERM mid-run ends cleanly (no traceback, its documented exit code).

A user's Ctrl-C in a terminal signals the whole foreground process group at
once; rclpy's own handlers used to shut the context down inside a running
callback, whose next publish raised "publisher's context is invalid". Here the
README's by-hand graph is started as one process group and interrupted
mid-run, and a composed host (``--compose all``) is stopped by the runner.
"""
from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cnc_contour_control.core.stop_signals import STACK_DUMP_SIGNAL
from cnc_contour_control.testing import stop_processes, wait_until

ROOT = Path(__file__).resolve().parents[2]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
CONFIG = ROOT / "install" / "cnc_contour_control" / "share" / "cnc_contour_control" / "config"
PARAMS = CONFIG / "paper000_circle_high.recorded.params.yaml"
#: The by-hand graph: executable and its own ROS arguments (the README's five shells).
NODES = {
    "recorder": ["recorder"],
    "plant": ["plant"],
    "servo_x": ["servo", "-r", "__node:=servo_x"],
    "servo_y": ["servo", "-r", "__node:=servo_y"],
    "interpolator": ["interpolator"],
}
pytestmark = pytest.mark.e2e
#: How long the nodes may take, all together, to end cleanly after the signal: a guard against a hang, not a
#: requirement (with two busy loops beside a 2-core run, one node took more than 30 s of the former per-node wait).
EXIT_WAIT_S = 180.0



def _status(summary: Path) -> str | None:
    try:
        return json.loads(summary.read_text()).get("status")
    except (OSError, ValueError):
        return None


def _params_file(tmp_path: Path) -> Path:
    """The installed recorded-graph parameters with a summary file, the program by absolute path, and 600 s to run.

    Edited as text: rcl's YAML reads an unquoted ``y`` (an axis) as a bool, so the file is not dumped anew.
    The program's own 6.5 s of simulation take well under a second of lockstep, less than the plant's 1 s
    between "running" summaries: the run could end before the test saw it run.
    """
    text, count = re.subn(r'"duration_s": [0-9.e+-]+', '"duration_s": 600.0', PARAMS.read_text())
    assert count == 1, f"{PARAMS} sets the plant's duration_s once"
    replacements = {'"summary_file": ""': f'"summary_file": "{tmp_path / "summary.json"}"',
                    '"program_file": "': f'"program_file": "{CONFIG}/'}
    for old, new in replacements.items():
        assert text.count(old) == 1, f"{PARAMS} sets {old} once"
        text = text.replace(old, new)
    path = tmp_path / "graph.params.yaml"
    path.write_text(text)
    return path


def _start_group(tmp_path: Path, params: Path) -> dict[str, subprocess.Popen[bytes]]:
    """Every node of the by-hand graph in one new process group (a terminal's foreground job)."""
    processes: dict[str, subprocess.Popen[bytes]] = {}
    for name, command in NODES.items():
        extra = ["-p", f"output:={tmp_path / 'bag'}"] if name == "recorder" else []
        group = processes["recorder"].pid if processes else 0
        with open(tmp_path / f"{name}.log", "wb") as log:
            processes[name] = subprocess.Popen(
                [command[0], "--ros-args", "-r", "__ns:=/cnc", *command[1:], "--params-file", str(params), *extra],
                stdout=log, stderr=subprocess.STDOUT, process_group=group)
    return processes


def _exit_codes(processes: dict[str, subprocess.Popen[bytes]], tmp_path: Path) -> dict[str, int]:
    """Each node's exit code within EXIT_WAIT_S; a node still running then prints its threads' stacks
    (:data:`~cnc_contour_control.core.stop_signals.STACK_DUMP_SIGNAL`) into its log, and the failure shows them."""
    deadline_s = time.monotonic() + EXIT_WAIT_S
    for process in processes.values():
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(timeout=max(0.0, deadline_s - time.monotonic()))
    stuck = {name: tmp_path / f"{name}.log" for name, p in processes.items() if p.poll() is None}
    for name in stuck:
        processes[name].send_signal(STACK_DUMP_SIGNAL)
    dumped_by_s = time.monotonic() + 10.0  # the stacks are written from the signal handler, at once
    while stuck and time.monotonic() < dumped_by_s and not all(
            "most recent call first" in log.read_text(errors="replace") for log in stuck.values()):
        time.sleep(0.1)
    assert not stuck, (f"not ended {EXIT_WAIT_S:.0f} s after the signal: {list(stuck)}; their logs:\n"
                       + "\n".join(f"--- {name}\n{log.read_text(errors='replace')}" for name, log in stuck.items()))
    return {name: int(process.returncode) for name, process in processes.items()}


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=lambda s: signal.Signals(s).name)
def test_a_signal_to_the_by_hand_graph_mid_run_ends_every_node_cleanly(tmp_path: Path, sig: int) -> None:
    processes = _start_group(tmp_path, _params_file(tmp_path))
    try:
        wait_until(lambda: _status(tmp_path / "summary.json") == "running"
                  or any(p.poll() is not None for p in processes.values()), 90.0, "the plant to run")
        exited = {name: p.returncode for name, p in processes.items() if p.poll() is not None}
        assert not exited, f"every node runs until the signal; exited: {exited}"
        os.killpg(processes["recorder"].pid, sig)
        codes = _exit_codes(processes, tmp_path)
    finally:
        stop_processes(processes.values())
    logs = {name: (tmp_path / f"{name}.log").read_text() for name in NODES}
    assert codes == dict.fromkeys(NODES, 0), logs
    assert not [name for name, text in logs.items() if "Traceback" in text or "FAULT" in text], logs
    assert _status(tmp_path / "summary.json") == "interrupted"
    assert (tmp_path / "bag" / "metadata.yaml").is_file(), "the recorder closed its bag"


def test_a_composed_host_stopped_by_the_runner_ends_cleanly(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    runner = subprocess.Popen([sys.executable, "-m", "cnc_tools.cli.main", "run", str(CIRCLE), "--out", str(run_dir),
                               "--set", "duration_s=600", "--compose", "all"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_until(lambda: _status(run_dir / "summary.json") == "running", 90.0, "the composed graph to run")
        runner.send_signal(signal.SIGINT)  # the runner passes it on: SIGINT to the host
        _, err = runner.communicate(timeout=EXIT_WAIT_S)
    finally:
        stop_processes([runner])
    assert runner.returncode == 128 + signal.SIGINT, err
    host_log = (run_dir / "composed.log").read_text()
    assert "Traceback" not in host_log and "FAULT" not in host_log, host_log
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["exit_codes"]["plant"] == 0, summary
    assert (run_dir / "bag" / "metadata.yaml").is_file(), "the recorder member closed its bag"
