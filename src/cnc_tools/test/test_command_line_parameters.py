"""A ``-p NAME:=VALUE`` on a node's command line wins over its ``--params-file``, as ROS users expect (issue 22).

rclpy applies a file's ``/<ns>/<node>`` section after the ``/**`` entries where
rcl puts a command line's ``-p``, so the README's ``-p summary_file:=FILE`` lost
to the installed file's plant ``summary_file: ""``.
"""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from cnc_contour_control.nodes.common import EXIT_FAULT, command_line_first
from cnc_contour_control.nodes.parameters import command_line_rules
from cnc_tools.runs.dds import claim_free_domain_id, loopback_env
from cnc_tools.runs.graph import find_executable
from cnc_tools.runs.lifetime import stop_process

INSTALLED = (Path(__file__).resolve().parents[2] / "cnc_contour_control" / "config"
             / "paper000_circle_high.recorded.params.yaml")


def test_the_rules_are_those_of_the_ros_arguments_only() -> None:
    argv = ["plant", "-p", "not_ros:=1", "--ros-args", "-r", "__ns:=/a", "-p", "x:=1", "--param", "b:=[1, 2]",
            "--params-file", "f.yaml", "--", "-p", "after:=2", "--ros-args", "-p", "n:x:=3"]
    assert command_line_rules(argv) == ["x:=1", "b:=[1, 2]", "n:x:=3"]


def test_the_rules_come_after_the_nodes_own_arguments_unless_it_ignores_the_process_s() -> None:
    argv = ["plant", "--ros-args", "-p", "x:=1"]
    own = ["--ros-args", "--params-file", "f.yaml"]
    assert command_line_first({"cli_args": own}, argv)["cli_args"] == [*own, "--ros-args", "-p", "x:=1"]
    member = {"cli_args": own, "use_global_arguments": False}
    assert command_line_first(member, argv) == member
    assert command_line_first({"namespace": "/a"}, ["plant"]) == {"namespace": "/a"}


@pytest.mark.nodes
def test_a_plant_process_takes_its_p_values_over_the_installed_parameters_file(tmp_path: Path) -> None:
    """The README's by-hand plant with ``-p summary_file:=FILE``, and two more keys of the file's plant section
    (a short startup timeout: with no partners the plant faults after 1 s and writes its summary). In /cnc as the
    file names it, so in a domain of its own."""
    assert '"summary_file": ""' in INSTALLED.read_text() and '"startup_timeout_s": 90.0' in INSTALLED.read_text()
    summary = tmp_path / "summary.json"
    command = [str(find_executable("cnc_plant_sim", "plant")), "--ros-args", "-r", "__ns:=/cnc",
               "--params-file", str(INSTALLED), "-p", f"summary_file:={summary}",
               "-p", "command_timeout_s:=0.5", "-p", "startup_timeout_s:=1.0"]
    domain = claim_free_domain_id()
    try:
        with open(tmp_path / "plant.log", "wb") as log:
            process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT,
                                       env=loopback_env(domain_id=domain.domain_id), start_new_session=True)
        try:
            process.wait(timeout=60.0)  # with the file's 90 s startup timeout it would still wait
        except subprocess.TimeoutExpired:
            pass
        finally:
            stop_process(process, 15.0)
    finally:
        domain.release()
    output = (tmp_path / "plant.log").read_text()
    assert process.returncode == EXIT_FAULT, output
    assert summary.is_file(), f"no summary at the -p summary_file: {output}"
    result = json.loads(summary.read_text())
    assert result["status"] == "faulted" and "readers missing after 1.0 s" in result["faults"][0], result
    assert result["duration_s"] == pytest.approx(6.386566556118514), "the file's other values still apply"
