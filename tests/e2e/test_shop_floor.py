"""Tier 3: the shop floor, as a user drives it: nodes started by hand, programs by action, override, trips, reset.

Plant (lockstep, T = 10 ms, no end in sight), two servos (``ferror_action:
latch``, a following-error bound about three times the largest of normal
motion) and an action-mode interpolator (``feed_override_source: topic``)
run as separate processes, their parameter files from ``cnc-contour params``
as a user writes them, no runner. A probe node plays the operator: it sends
programs by action, turns the feed override knob and detunes an axis at run
time; the e-stop, the reset and the enable go through ``cnc-contour
machine`` (the README's commands), the refusals through the services.

1. a line and an arc complete (scores checked);
2. a long line at 50 % mid-way, then a feed hold (path speed 0 on the path),
   then 100 %: completes;
3. a line cancelled halfway: CANCELED, stopped on the path;
4. servo x's drive stops answering (its PID gains set to 0 at run time: the
   command stays where it was, 0 at rest), then a program: the trip
   latches it, the goal ends FAULTED naming the axis, every node is latched,
   a goal is rejected with the cause;
5. the e-stop pressed: enable and reset refused while it is true; released:
   reset and enable on plant and servos, and a last program completes.
"""
from __future__ import annotations

import math
import subprocess
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool, Trigger

from cnc_contour_control.nodes.common import stamp_to_ns
from cnc_contour_control.testing import ThreadSafeActionClient, TopicProbe, stop_processes
from cnc_contour_interfaces.action import RunProgram
from cnc_contour_interfaces.msg import FeedOverride, Reference
from cnc_tools.cli.main import main as cli
from cnc_tools.runs.graph import find_executable

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "paper000_circle_high.yaml"
NS = "/cnc"
#: The servos' trip: 0.8 mm at rest + 0.4 mm at 2000 mm/min (the axes' limit). Largest following error of
#: normal motion at 1200 mm/min: 0.31 mm on the scenario's circle (engine), up to 0.48 mm where this PID
#: starts or stops a move (tests/test_program_action.py).
FERROR = {"servo.min_ferror_m": 8e-4, "servo.ferror_m": 4e-4, "servo.ferror_velocity_m_s": 1 / 30}
NODES = {  # node name -> (package, executable, parameters beside the file's)
    "plant": ("cnc_plant_sim", "plant", ["-p", "summary_file:={folder}/summary.json"]),
    "servo_x": ("cnc_contour_control", "servo", ["-p", "ferror_action:=latch"]),
    "servo_y": ("cnc_contour_control", "servo", ["-p", "ferror_action:=latch"]),
    "interpolator": ("cnc_contour_control", "interpolator",
                     ["-p", "program_source:=action", "-p", "feed_override_source:=topic",
                      "-p", "feedback_period_s:=0.05"]),
}
MACHINE = ("plant", "servo_x", "servo_y")
PANEL = ["--nodes", *MACHINE]  # cnc-contour machine: the nodes to wait for
FIRST = "G1 X5 F1200\nG3 X10 Y5 I0 J5\n"   # a line and a quarter arc from the origin, ends at (10, 5) mm
SECOND = "G1 X40 F1200\n"                   # 30 mm along y = 5 mm: 50 %, hold, 100 %
THIRD = "G1 X10 F600\n"                     # 30 mm back in 3 s: cancelled halfway, 1.5 s before its end
TRIPPED = "G1 X40 F1200\n"                  # servo x's gains at 0: the trip stops it
LAST = "G1 X0 Y0 F1200\n"                   # home, after reset and enable
Y_PATH_M = 5e-3
#: The scenario's PID gains (paper 000's Table 4 in time units).
GAINS = {"kp": 2.4, "ki": 10.0, "kd": 0.067}

pytestmark = pytest.mark.e2e


@contextmanager
def nodes_by_hand(folder: Path) -> Iterator[dict[str, subprocess.Popen[bytes]]]:
    """The parameter files as a user writes them, then each node in its own process; all stopped by pid."""
    sets = [f"--set={key}={value}" for key, value in {**FERROR, "duration_s": 1.0e5}.items()]
    assert cli(["params", str(SCENARIO), "--out", str(folder / "params"), *sets]) == 0
    processes: dict[str, subprocess.Popen[bytes]] = {}
    try:
        for name, (package, executable, extra) in NODES.items():  # the natural order: plant, servos, interpolator
            command = [str(find_executable(package, executable)), "--ros-args", "-r", f"__ns:={NS}",
                       "-r", f"__node:={name}", "--params-file", str(folder / "params" / f"{name}.params.yaml"),
                       *(word.format(folder=folder) for word in extra)]
            with open(folder / f"{name}.log", "wb") as log:
                processes[name] = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
        yield processes
    finally:
        stop_processes(processes.values())


class Operator:
    """The probe node's hands: goals, the feed override knob, the e-stop, services, parameters."""

    def __init__(self, probe: TopicProbe) -> None:
        self.probe = probe
        self.client = ThreadSafeActionClient(probe.node, RunProgram, f"{NS}/run_program")
        self.override = probe.publisher(FeedOverride, f"{NS}/feed_override", 10)
        self.feedback: list[Any] = []

    def wait(self, condition: Callable[[], bool], timeout_s: float, what: str) -> None:
        self.probe.wait_for(condition, timeout_s, what)

    def run_when_ready(self, gcode: str, timeout_s: float) -> Any:
        """Run ``gcode`` until a goal is not refused (the machine's state reaches the interpolator by /diagnostics);
        its result."""
        results: list[Any] = []

        def ran() -> bool:
            results.append(self.result(self.send(gcode)))
            return bool(results[-1].outcome != RunProgram.Result.REJECTED)

        self.wait(ran, timeout_s, "a goal not refused")
        return results[-1]

    def send(self, gcode: str) -> Any:
        """A goal's handle once answered (``accepted`` tells); its feedback collected."""
        self.feedback.clear()
        future = self.client.send_goal_async(RunProgram.Goal(gcode=gcode),
                                             feedback_callback=lambda msg: self.feedback.append(msg.feedback))
        self.wait(future.done, 20.0, "the goal's answer")
        return future.result()

    def result(self, handle: Any, timeout_s: float = 60.0) -> Any:
        future = handle.get_result_async()
        self.wait(future.done, timeout_s, "the goal's result")
        return future.result().result

    def progress(self) -> float:
        """Share of the running program's path done, from the latest feedback (0 before any)."""
        return self.feedback[-1].path_length_m / self.feedback[-1].total_length_m if self.feedback else 0.0

    def knob(self, ratio: float) -> None:
        self.override.publish(FeedOverride(requested_ratio=ratio, applied_ratio=ratio))

    def set_gains(self, node: str, gains: dict[str, float]) -> None:
        request = SetParameters.Request(parameters=[Parameter(f"gains.{name}", value=value).to_parameter_msg()
                                                    for name, value in gains.items()])
        assert all(r.successful for r in self.probe.call(SetParameters, f"{NS}/{node}/set_parameters", request).results)

    def enable(self, node: str) -> Any:
        return self.probe.call(SetBool, f"{NS}/{node}/enable", SetBool.Request(data=True))

    def reset(self, node: str) -> Any:
        return self.probe.call(Trigger, f"{NS}/{node}/reset", Trigger.Request())


def statuses(probe: TopicProbe, node: str) -> list[Any]:
    return [s for a in probe.received("/diagnostics") for s in a.status if s.name == f"{NS}/{node}"]


def latch_value(probe: TopicProbe, node: str, key: str) -> str:
    """``key`` of the node's latest status that reports its latch ("" before any)."""
    reports = [{kv.key: kv.value for kv in s.values} for s in statuses(probe, node)]
    reports = [r for r in reports if key in r]
    return reports[-1][key] if reports else ""


def latched_now(probe: TopicProbe, node: str) -> bool:
    """The node's latest latch report says latched."""
    return latch_value(probe, node, "estop_latched") == "true"


def references(probe: TopicProbe, since_ns: int = 0) -> list[Any]:
    return [m for m in probe.received(f"{NS}/reference") if stamp_to_ns(m.header.stamp) >= since_ns]


def assert_scored(result: Any, bound_m: float) -> None:
    for name in ("max_contour_error_m", "rms_contour_error_m", "max_following_error_m", "cycle_time_s"):
        assert math.isfinite(getattr(result, name)) and getattr(result, name) >= 0.0, name
    assert result.max_contour_error_m < bound_m and result.ticks > 0
    assert result.path_length_m == pytest.approx(result.total_length_m)


def run_override_and_hold(op: Operator, probe: TopicProbe) -> tuple[Any, int]:
    """Program 2: 50 % from a fifth of the path, a hold from half of it, 100 % again; its result and start."""
    def at_rest_at_the_end_of_program_1() -> bool:  # the probe's copy of the references lags under load
        refs = references(probe)
        return bool(refs) and refs[-1].position_m[1] == pytest.approx(Y_PATH_M, abs=1e-12) \
            and not any(refs[-1].velocity_m_s)

    op.wait(at_rest_at_the_end_of_program_1, 10.0, "the probe to see program 1's end")
    start_ns = stamp_to_ns(references(probe)[-1].header.stamp)
    handle = op.send(SECOND)
    assert handle.accepted
    op.wait(lambda: op.progress() > 0.2, 30.0, "a fifth of program 2")
    op.knob(0.5)
    op.wait(lambda: op.feedback[-1].feed_override_ratio == 0.5, 10.0, "50 % echoed in the feedback")
    op.wait(lambda: op.progress() > 0.5, 30.0, "half of program 2")
    op.knob(0.0)
    op.wait(lambda: sum(m.feed_override_ratio == 0.0 for m in references(probe, start_ns)) > 30, 30.0,
            "0.3 s held")
    op.knob(1.0)
    return op.result(handle), start_ns


def check_override_and_hold(result: Any, refs: list[Any]) -> None:
    """50 % and 0 echoed in the reference; the hold stopped on the path and stood still; completed."""
    ratios = np.array([m.feed_override_ratio for m in refs])
    feeds = np.array([m.feed_m_s for m in refs])
    positions = np.array([list(m.position_m) for m in refs])
    assert result.outcome == RunProgram.Result.COMPLETED and result.path_length_m == pytest.approx(0.03)
    assert np.any(ratios == 0.5) and np.any(ratios == 0.0) and ratios[-1] == 1.0
    assert np.all(feeds[ratios == 0.5] == pytest.approx(0.5 * 0.02)), "50 % of F1200"
    held = positions[ratios == 0.0]
    assert np.all(feeds[ratios == 0.0] == 0.0) and np.all(held == held[0]), "the hold: path speed 0, at rest"
    assert np.all(positions[:, 1] == pytest.approx(Y_PATH_M, abs=1e-12)), "on the path throughout"
    assert 0.01 + 0.5 * 0.03 < held[0, 0] < 0.04, "held beyond half of the line"


def trip_servo_x(op: Operator, probe: TopicProbe) -> Any:
    """Program 4 with servo x's gains at 0: its result (FAULTED by the trip) once every node is latched."""
    op.set_gains("servo_x", dict.fromkeys(GAINS, 0.0))  # at rest: the axis stands, but cannot follow a move
    handle = op.send(TRIPPED)
    assert handle.accepted
    result = op.result(handle, 30.0)
    op.wait(lambda: all(latched_now(probe, node) for node in MACHINE), 10.0, "every node latched")
    op.set_gains("servo_x", GAINS)  # retuned while latched (the law is frozen): the reset may follow
    return result


def test_a_shop_floor_day_by_action_with_override_hold_cancel_trip_estop_and_reset(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    probed = {f"{NS}/reference": Reference, f"{NS}/joint_states": JointState, "/diagnostics": DiagnosticArray}
    with TopicProbe(probed) as probe, nodes_by_hand(tmp_path) as processes:
        op = Operator(probe)
        op.wait(op.client.server_is_ready, 60.0, "the RunProgram server")
        op.wait(lambda: len(references(probe)) > 10, 60.0, "the machine ticking, holding")

        result1 = op.result(op.send(FIRST))
        result2, start2_ns = run_override_and_hold(op, probe)
        refs2 = references(probe, start2_ns)

        third = op.send(THIRD)
        assert third.accepted
        op.wait(lambda: op.progress() > 0.45, 30.0, "program 3 halfway")
        op.wait(third.cancel_goal_async().done, 10.0, "the cancel's answer")
        result3 = op.result(third)
        stopped_m = list(references(probe)[-1].position_m)

        result4 = trip_servo_x(op, probe)
        refused_goal = op.result(op.send(LAST))  # every goal is accepted; a refused one ends REJECTED with the reason
        assert cli(["machine", "estop", *PANEL]) == 0  # pressed: every node's e-stop input true (reported each second)
        op.wait(lambda: all(latch_value(probe, node, "estop_input") == "true" for node in MACHINE), 20.0,
                "the e-stop input true on every node")
        stopped_refs = references(probe)[-50:]  # the machine off: the reference at the measured position
        refused = {node: op.enable(node) for node in MACHINE}
        reset_refused = op.reset("plant")
        capsys.readouterr()
        assert cli(["machine", "release", *PANEL]) == 0  # a reset is allowed once a node has the input false
        op.wait(lambda: cli(["machine", "reset", *PANEL]) == 0, 20.0, "every node reset once the e-stop is released")
        assert cli(["machine", "enable", *PANEL]) == 0
        panel = capsys.readouterr().out
        op.wait(lambda: not any(latched_now(probe, node) for node in MACHINE), 10.0, "the latches cleared")
        result5 = op.run_when_ready(LAST, 10.0)
        codes = {name: process.poll() for name, process in processes.items()}
        measured = {stamp_to_ns(m.header.stamp): list(m.position) for m in probe.received(f"{NS}/joint_states")}
        errors = [s for node in MACHINE for s in statuses(probe, node) if s.level == DiagnosticStatus.ERROR]
        rejections = [s.message for s in statuses(probe, "interpolator") if "rejected" in s.message]

    assert codes == dict.fromkeys(NODES), "every node stayed up"
    assert result1.outcome == RunProgram.Result.COMPLETED
    assert_scored(result1, min(5e-4, math.sqrt(2) * result1.max_following_error_m))
    check_override_and_hold(result2, refs2)
    assert result3.outcome == RunProgram.Result.CANCELED
    assert 0.4 * 0.03 < result3.path_length_m < 0.03 and stopped_m[1] == pytest.approx(Y_PATH_M, abs=1e-12)

    assert result4.outcome == RunProgram.Result.FAULTED
    assert "servo x: following error" in result4.reason and f"{NS}/servo_x" in result4.reason, result4.reason
    assert [s.name for s in errors] == [f"{NS}/servo_x"] and "exceeds the bound" in errors[0].message
    assert any("the machine is stopped" in m and "servo x: following error" in m for m in rejections)
    assert refused_goal.outcome == RunProgram.Result.REJECTED, "no goal while the machine is stopped"
    assert "the machine is stopped" in refused_goal.reason and refused_goal.ticks == 0
    assert all(not answer.success and "enable refused: e-stop latched" in answer.message
               for answer in refused.values())
    assert "servo x: following error" in refused["servo_x"].message
    both = [ref for ref in stopped_refs if stamp_to_ns(ref.header.stamp) in measured]  # the probe may drop some
    assert len(both) >= 10, f"{len(both)} of {len(stopped_refs)} stopped ticks with their joint state"
    for ref in both:
        assert list(ref.position_m) == measured[stamp_to_ns(ref.header.stamp)] and not any(ref.velocity_m_s)
    assert not reset_refused.success and "e-stop input is still true" in reset_refused.message
    assert all(f"{NS}/{node}/enable: ok: enabled" in panel for node in MACHINE), panel
    assert all(f"{NS}/{node}/reset: ok: latch cleared" in panel for node in MACHINE), panel
    assert result5.outcome == RunProgram.Result.COMPLETED
    assert_scored(result5, 5e-4)
