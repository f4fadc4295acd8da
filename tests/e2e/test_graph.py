"""Tier 3: the whole node graph as separate processes over real DDS (loopback only)."""
from __future__ import annotations

import os
import signal
from pathlib import Path

import numpy as np
import pytest
from sensor_msgs.msg import JointState

from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.testing import TopicProbe, dds_ports, ephemeral_port_range, udp_sockets
from cnc_contour_interfaces.msg import AxisCommand, Reference
from cnc_tools.analysis.verdict import judge
from cnc_tools.bagio.bag import read_bag
from cnc_tools.runs.engine import run_engine, tick_count
from cnc_tools.runs.graph import GraphRun, graph_nodes, run_graph
from cnc_tools.runs.namespaces import run_namespace
from cnc_tools.runs.outputs import judge_bag
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
# A probe counts as one extra reader of every lockstep topic (as a recorder does).
PROBED = {"/cnc/joint_states": JointState, "/cnc/reference": Reference,
          "/cnc/servo/x/command": AxisCommand, "/cnc/servo/y/command": AxisCommand}

pytestmark = pytest.mark.e2e


def test_lockstep_graph_matches_engine_to_1e9(tmp_path: Path) -> None:
    # Read from the bag: the recorder is a reader the stages wait for by name. A probe that is only counted
    # (extra_subscribers) is matched by a writer before it has matched the writer itself, and over shared
    # memory the first command left in that window once (KeyError: tick 0).
    scenario = load_scenario(CIRCLE, {"duration_s": 2.0})
    result = run_graph(scenario, tmp_path, record=True)
    recorded = read_bag(result.bag_path)
    engine = run_engine(scenario)
    assert result.summary["ticks"] == tick_count(scenario) == engine.ticks == len(recorded.joint_states.stamp_ns)
    assert result.faults == [] and recorded.integrity.complete, recorded.integrity.describe()
    np.testing.assert_array_equal(recorded.joint_states.stamp_ns, engine.joint_states.stamp_ns)
    np.testing.assert_allclose(recorded.joint_states.position_m, engine.joint_states.position_m, rtol=0.0, atol=1e-9)
    for i, axis in enumerate(scenario.axes):
        series = recorded.commands[axis]
        np.testing.assert_array_equal(series.stamp_ns, engine.joint_states.stamp_ns)
        np.testing.assert_allclose(series.command, engine.command_array()[:, i], rtol=0.0, atol=1e-9)
    assert np.ptp(engine.joint_states.position_m[:, 1]) > 1e-3, "the axes really moved"
    graph_verdict, engine_verdict = judge_bag(result.bag_path)[1], judge(engine)
    assert graph_verdict.complete and engine_verdict.complete, (graph_verdict.describe(), engine_verdict.describe())
    assert result.summary["ends_by"] == engine.summary["ends_by"] == "duration", "cut by its duration_s, as asked"


def test_dds_sockets_stay_on_loopback(tmp_path: Path) -> None:
    # The sockets are read while every node still runs: 20000 ticks, ended once read (a lockstep graph can run
    # hundreds of ticks ahead of this process's probe, and 1000 ticks take 0.5 s over shared memory).
    scenario = load_scenario(CIRCLE, {"duration_s": 200.0})
    domain = int(os.environ["ROS_DOMAIN_ID"])
    well_known, (low, high) = dds_ports(domain), ephemeral_port_range()
    with TopicProbe(PROBED) as probe:
        with GraphRun(graph_nodes(scenario, tmp_path, extra_subscribers=1), tmp_path) as run:
            probe.wait_for(lambda: len(probe.received("/cnc/joint_states")) > 5, 30.0, "the run to be going")
            sockets = {name: udp_sockets(p.pid) for name, p in run.processes.items()}
            assert all(code is None for code in run.exit_codes().values()), "read from running nodes"
    for name, bound in sockets.items():
        assert bound, f"{name} holds no UDP socket: the check saw nothing"
        receiving = [(ip, port) for ip, port in bound if port in well_known]
        assert receiving and all(ip == "127.0.0.1" for ip, _ in receiving), (name, receiving)
        elsewhere = [(ip, port) for ip, port in bound if ip not in ("127.0.0.1", "::1")]
        # Fast DDS's send-only sockets (docs/design.md, "DDS on loopback"): ephemeral ports only.
        assert all(low <= port <= high and port not in well_known for _, port in elsewhere), (name, elsewhere)


def test_node_killed_mid_run_is_named_and_everything_is_reaped(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE, {"duration_s": 200.0})  # the kill comes mid-run however fast the graph runs
    ns = run_namespace()  # the killed servo stays in the graph until its DDS lease ends: not in the file's /cnc
    with TopicProbe({topic.replace("/cnc", ns, 1): kind for topic, kind in PROBED.items()}) as probe:
        with pytest.raises(FaultError, match=r"node servo_y \(pid \d+\) exited with code -9") as caught:
            with GraphRun(graph_nodes(scenario, tmp_path, extra_subscribers=1), tmp_path, namespace=ns) as run:
                probe.wait_for(lambda: len(probe.received(f"{ns}/joint_states")) > 20, 30.0, "ticks")
                os.kill(run.processes["servo_y"].pid, signal.SIGKILL)
                run.wait("plant", 60.0)
    assert "servo_y" in str(caught.value)
    assert all(p.returncode is not None for p in run.processes.values()), "all node processes reaped"


def test_missing_input_past_timeout_is_a_fault_naming_the_topic(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE, {"duration_s": 200.0})  # the stop comes mid-run however fast the graph runs
    nodes = graph_nodes(scenario, tmp_path, extra_subscribers=1, input_timeout_s=1.0)
    with TopicProbe(PROBED) as probe:
        with pytest.raises(FaultError) as caught:
            with GraphRun(nodes, tmp_path) as run:
                probe.wait_for(lambda: len(probe.received("/cnc/joint_states")) > 10, 30.0, "ticks")
                interpolator = run.processes["interpolator"]
                os.kill(interpolator.pid, signal.SIGSTOP)
                try:
                    run.wait("plant", 60.0)
                finally:
                    os.kill(interpolator.pid, signal.SIGCONT)
    message = str(caught.value)
    assert "servo_" in message and "no /cnc/reference for tick" in message, message
    assert all(p.returncode is not None for p in run.processes.values())


def test_realtime_mode_runs_on_the_wall_clock_and_counts_late_commands(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE, {"mode": "realtime", "duration_s": 1.0})
    result = run_graph(scenario, tmp_path)
    summary = result.summary
    # A loaded machine may push the late share over its bound in the first 100 ticks: that fault is the watchdog's
    # verdict (tested in test_safety_graph), and the late commands it counted are this test's subject too.
    assert all("late" in fault for fault in result.faults), result.faults
    assert summary["ticks"] >= 1
    if result.faults:
        assert summary["late_commands"] > 0, "the fault counted the late commands"
    else:
        assert summary["simulated_time_s"] > 1.0 and summary["late_commands"] >= 0
    # Each tick advances by the measured wall period: simulated time tracks wall time.
    assert summary["wall_time_s"] >= 0.9 * summary["simulated_time_s"]


def test_three_axis_gcode_program_runs_through_the_graph_like_the_engine(tmp_path: Path) -> None:
    scenario = load_scenario(ROOT / "scenarios" / "helix_3axis.yaml")
    assert scenario.axes == ("x", "y", "z")
    result = run_graph(scenario, tmp_path, record=True)
    assert result.faults == []
    from cnc_tools.bagio.bag import read_bag

    recorded = read_bag(result.bag_path)
    engine = run_engine(scenario)
    np.testing.assert_allclose(recorded.joint_states.position_m, engine.joint_states.position_m, rtol=0.0, atol=1e-9)
    assert np.ptp(engine.joint_states.position_m[:, 2]) > 1.5e-3, "Z really moved"
