"""Tier 3: a JointTrajectory naming two of three axes, by FollowTrajectory, on real processes.

Plant, three servos (x, y, z: the helix_3axis scenario's paper-000 drives and
PID) and an action-mode interpolator run as separate processes from the
parameter files ``cnc-contour params`` writes, no runner. A probe sends a
FollowTrajectory goal naming y and x only: both move to their points at their
``time_from_start``, z holds where it stood (reference unchanged, measured
within micrometres), the goal succeeds (every axis within its default goal
tolerance, stopped), no node faults or latches, and ``~/controller_state``
carries reference, feedback and error of all three axes.
"""
from __future__ import annotations

import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from cnc_contour_control.nodes.common import stamp_to_ns
from cnc_contour_control.testing import ThreadSafeActionClient, TopicProbe, stop_processes
from cnc_contour_interfaces.action import FollowTrajectory
from cnc_contour_interfaces.msg import ControllerState, Reference
from cnc_tools.cli.main import main as cli
from cnc_tools.runs.graph import find_executable

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "helix_3axis.yaml"
NS = "/cnc"
NODES = {  # node name -> (package, executable, parameters beside the file's)
    "plant": ("cnc_plant_sim", "plant", []),
    "servo_x": ("cnc_contour_control", "servo", []),
    "servo_y": ("cnc_contour_control", "servo", []),
    "servo_z": ("cnc_contour_control", "servo", []),
    "interpolator": ("cnc_contour_control", "interpolator", ["-p", "program_source:=action"]),
}
#: The move: x +3 mm and y +2 mm in 2 s (cubic Hermite, at rest at both ends), z not named.
MOVE_M = {"x": 3e-3, "y": 2e-3}
#: How far z may stand from where it was while x and y move: its loop holds a constant reference.
Z_HOLD_M = 1e-6

pytestmark = pytest.mark.e2e


@contextmanager
def nodes_by_hand(folder: Path) -> Iterator[dict[str, subprocess.Popen[bytes]]]:
    """The scenario's parameter files, then each node in its own process; all stopped by pid."""
    assert cli(["params", str(SCENARIO), "--out", str(folder / "params"), "--set=duration_s=1e5"]) == 0
    processes: dict[str, subprocess.Popen[bytes]] = {}
    try:
        for name, (package, executable, extra) in NODES.items():
            command = [str(find_executable(package, executable)), "--ros-args", "-r", f"__ns:={NS}",
                       "-r", f"__node:={name}", "--params-file", str(folder / "params" / f"{name}.params.yaml"),
                       *extra]
            with open(folder / f"{name}.log", "wb") as log:
                processes[name] = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
        yield processes
    finally:
        stop_processes(processes.values())


def test_a_trajectory_of_x_and_y_moves_them_while_z_holds_and_nothing_faults(tmp_path: Path) -> None:
    state_topic = f"{NS}/interpolator/controller_state"
    probed = {f"{NS}/reference": Reference, f"{NS}/joint_states": JointState, "/diagnostics": DiagnosticArray,
              state_topic: ControllerState}
    with TopicProbe(probed) as probe, nodes_by_hand(tmp_path) as processes:
        client = ThreadSafeActionClient(probe.node, FollowTrajectory, f"{NS}/follow_trajectory")
        probe.wait_for(client.server_is_ready, 60.0, "the FollowTrajectory server")
        probe.wait_for(lambda: len(probe.received(f"{NS}/joint_states")) > 20, 60.0, "the machine ticking")
        start = list(probe.received(f"{NS}/joint_states")[-1].position)
        end = {"y": start[1] + MOVE_M["y"], "x": start[0] + MOVE_M["x"]}
        trajectory = JointTrajectory(joint_names=["y", "x"], points=[
            JointTrajectoryPoint(positions=[end["y"], end["x"]], velocities=[0.0, 0.0],
                                 time_from_start=Duration(sec=2))])
        future = client.send_goal_async(FollowTrajectory.Goal(trajectory=trajectory))
        probe.wait_for(future.done, 20.0, "the goal's answer")
        handle = future.result()
        result_future = handle.get_result_async()
        probe.wait_for(result_future.done, 60.0, "the goal's result")
        result = result_future.result().result
        codes = {name: process.poll() for name, process in processes.items()}
        states = probe.received(state_topic)
        measured = [list(m.position) for m in probe.received(f"{NS}/joint_states")]
        references = [list(m.position_m) for m in probe.received(f"{NS}/reference")]
        errors = [s for m in probe.received("/diagnostics") for s in m.status if s.level == DiagnosticStatus.ERROR]

    assert codes == dict.fromkeys(NODES), "every node stayed up"
    assert result.error_code == FollowTrajectory.Result.SUCCESSFUL, result.error_string
    assert not errors, [f"{s.name}: {s.message}" for s in errors]
    assert references[-1][0] == pytest.approx(end["x"], abs=1e-12)
    assert references[-1][1] == pytest.approx(end["y"], abs=1e-12)
    assert len({r[2] for r in references}) == 1, "z's reference held, unchanged"
    assert measured[-1][0] == pytest.approx(end["x"], abs=1e-5), "x within its goal tolerance (0.01 mm)"
    assert measured[-1][1] == pytest.approx(end["y"], abs=1e-5)
    assert max(abs(m[2] - start[2]) for m in measured) < Z_HOLD_M, "z held"
    state = states[-1]
    assert list(state.joint_names) == ["x", "y", "z"] and not state.output_known
    assert stamp_to_ns(state.header.stamp) > 0 and len(state.error_position_m) == 3
