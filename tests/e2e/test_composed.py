"""The composed mode: the loop's nodes (or all) in one process on one executor, the same bag as the engine's."""
from __future__ import annotations

import json
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
from rclpy.context import Context

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.nodes.common import SuiteNode
from cnc_contour_control.testing import TopicProbe, all_alive
from cnc_contour_interfaces.msg import ContourError
from cnc_tools.bagio.bag import read_bag
from cnc_tools.nodes.composed_host import EXIT_RAISED, ComposedHost
from cnc_tools.nodes.host_spec import HOST, MemberExit, exits_path, read_exits
from cnc_tools.runs.compose import group_nodes
from cnc_tools.runs.engine import run_engine, tick_count
from cnc_tools.runs.graph import NodeDied, run_graph
from cnc_tools.runs.graph_nodes import graph_specs, recorder_spec
from cnc_tools.runs.lifetime import RunInterrupted
from cnc_tools.runs.scenario import Scenario, load_scenario

pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parents[2]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
LOOP = {"plant", "interpolator", "servo_x", "servo_y", "estimator", "compensator"}


def _cross_axis(tmp: Path, name: str, duration_s: float = 0.6) -> Scenario:
    """The circle at 1 ms with the window estimator and a learning neural compensator saving its state."""
    return load_scenario(CIRCLE, {"sample_time_s": 0.001, "duration_s": duration_s,
                                  "estimator": {"method": "window"},
                                  "compensator": {"method": "neural", "state_out": str(tmp / f"{name}.npz")}})


@pytest.mark.parametrize(("mode", "composed"), [("loop", LOOP), ("all", LOOP | {"recorder"})])
def test_composed_lockstep_run_records_the_engines_bag(tmp_path: Path, mode: str, composed: set[str]) -> None:
    scenario = _cross_axis(tmp_path, "graph")
    result = run_graph(scenario, tmp_path / "run", record=True, compose=mode, timeout_s=300.0)
    assert result.faults == [] and result.summary["status"] == "finished"
    pids = json.loads((tmp_path / "run" / "pids.json").read_text())
    assert {name for name, pid in pids["nodes"].items() if pid == pids["processes"][HOST]} == composed
    assert sorted(pids["processes"]) == sorted({HOST} | (set(pids["nodes"]) - composed))
    recorded = read_bag(result.bag_path, namespace=result.namespace)
    engine = run_engine(_cross_axis(tmp_path, "engine"))
    assert recorded.ticks == engine.ticks == tick_count(scenario)
    np.testing.assert_allclose(recorded.joint_states.position_m, engine.joint_states.position_m, rtol=0, atol=1e-9)
    np.testing.assert_allclose(recorded.compensation.correction, engine.compensation.correction, rtol=0, atol=1e-9)
    for i, axis in enumerate(scenario.axes):
        np.testing.assert_allclose(recorded.commands[axis].command, engine.command_array()[:, i], rtol=0, atol=1e-9)
    assert np.abs(engine.compensation.correction).max() > 0, "the compensator acted"
    graph_state, engine_state = np.load(tmp_path / "graph.npz"), np.load(tmp_path / "engine.npz")
    for key in engine_state.files:  # the learner in the host saved its state before the host ended
        np.testing.assert_allclose(graph_state[key], engine_state[key], rtol=0, atol=1e-9, err_msg=key)


def test_fault_inside_the_composed_process_names_the_node_and_everything_is_reaped(tmp_path: Path) -> None:
    scenario = _cross_axis(tmp_path, "fault", duration_s=30.0)
    namespace = "/cnc/composed_fault"
    bad = ContourError(axis_names=["x", "y"], contour_error_m=float("nan"), tracking_error_m=[0.0, 0.0])
    with TopicProbe({}) as probe:
        publisher = probe.publisher(ContourError, f"{namespace}/contour_error")

        def inject() -> None:  # called by the runner every 50 ms: once ticks run, a NaN reaches the compensator
            summary = tmp_path / "run" / "summary.json"
            if summary.exists() and json.loads(summary.read_text() or "{}").get("ticks", 0) > 20:
                publisher.publish(bad)

        with pytest.raises(NodeDied) as caught:
            result = run_graph(scenario, tmp_path / "run", record=True, compose="loop", namespace=namespace,
                               on_poll=inject, timeout_s=300.0)
            pytest.fail(f"the run ended without the compensator's fault: {result.summary}")
    assert caught.value.node == "compensator"
    message = str(caught.value)
    assert "in the composed process" in message and "exited with code 3" in message, message
    assert f"{namespace}/contour_error" in message, message
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "node died" and "compensator" in summary["faults"][-1]
    pids = json.loads((tmp_path / "run" / "pids.json").read_text())
    assert set(pids["processes"]) == {HOST, "recorder"}
    assert not any(all_alive([pid]) for pid in pids["processes"].values()), "every process of the run reaped"
    assert read_exits(exits_path(tmp_path / "run", HOST))["compensator"].code == 3


def test_a_stopped_composed_run_closes_its_bag_and_says_interrupted(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE, {"duration_s": 600.0})  # 60000 ticks: stopped mid-run however fast

    def stop_once_running() -> None:  # the runner's path for SIGINT: its poll raises, the run is stopped and reaped
        summary = tmp_path / "summary.json"
        if summary.exists() and json.loads(summary.read_text() or "{}").get("ticks", 0) > 20:
            raise RunInterrupted(signal.SIGINT, tmp_path)

    with pytest.raises(RunInterrupted):
        run_graph(scenario, tmp_path, record=True, compose="all", on_poll=stop_once_running, timeout_s=300.0)
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "interrupted"
    pids = json.loads((tmp_path / "pids.json").read_text())
    assert set(pids["processes"]) == {HOST} and not all_alive(pids["processes"].values()), "the host reaped"
    assert (tmp_path / "bag" / "metadata.yaml").exists(), "the recorder in the host closed its bag"
    assert read_bag(tmp_path / "bag", commands=False).ticks > 20


class _Raiser(SuiteNode):
    """Raises a plain RuntimeError from its timer: a crash, not a fault of the suite."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("raiser", **kwargs)
        self.create_timer(0.01, self._boom)

    def _boom(self) -> None:
        raise RuntimeError("boom")


class _Counter(SuiteNode):
    """Finishes by itself after 30 timer ticks."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("counter", **kwargs)
        self.ticks = 0
        self.create_timer(0.01, self._tick)

    def _tick(self) -> None:
        self.ticks += 1
        self.finished = self.ticks >= 30


@pytest.mark.parametrize("executor", ["events", "single"])
def test_a_raising_member_ends_alone_named_and_the_others_go_on(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                 executor: str) -> None:
    monkeypatch.setenv("CNC_EXECUTOR", executor)
    context = Context()
    rclpy.init(context=context)
    host = ComposedHost(context, tmp_path / "exits.json")
    try:
        host.add("crash", _Raiser, ["--ros-args", "-r", "__ns:=/composed_test", "-r", "__node:=crash"])
        host.add("count", _Counter, ["--ros-args", "-r", "__ns:=/composed_test", "-r", "__node:=count"])
        host.spin()
        assert read_exits(tmp_path / "exits.json") == host.exits == {
            "crash": MemberExit(EXIT_RAISED, "RuntimeError: boom"), "count": MemberExit(0, "finished")}
    finally:
        host.close()
        rclpy.try_shutdown(context=context)


def test_compose_modes_group_the_loop_and_refuse_an_unknown_mode(tmp_path: Path) -> None:
    scenario = _cross_axis(tmp_path, "groups")
    nodes = [recorder_spec(scenario, tmp_path / "bag"), *graph_specs(scenario, tmp_path, 1, extra_readers=["recorder"])]
    groups = {mode: {g.name: {s.name for s in g.nodes} for g in group_nodes(nodes, mode)}
              for mode in ("none", "loop", "all")}
    assert groups["none"] == {s.name: {s.name} for s in nodes}
    assert groups["loop"] == {HOST: LOOP, "recorder": {"recorder"}}
    assert groups["all"] == {HOST: LOOP | {"recorder"}}
    with pytest.raises(ConfigError, match=r"compose must be one of \['all', 'loop', 'none'\], got 'some'"):
        group_nodes(nodes, "some")
