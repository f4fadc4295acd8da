"""Tier 3: machine safety in the node graph: following-error trip (= engine), late-share fault, e-stop, diagnostics."""
from __future__ import annotations

import re
from contextlib import ExitStack
from pathlib import Path

import numpy as np
import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool

from cnc_contour_control.nodes.safety_io import RUNNING
from cnc_contour_control.testing import TopicProbe
from cnc_contour_interfaces.msg import AxisCommand, Reference
from cnc_tools.analysis.verdict import judge
from cnc_tools.bagio.bag import read_bag
from cnc_tools.bagio.diagnostics import read_statuses
from cnc_tools.runs.engine import EngineFault, run_engine
from cnc_tools.runs.graph import NodeDied, run_graph
from cnc_tools.runs.outputs import judge_bag
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
#: Tight enough that axis x (peak 0.31 mm in this circle) trips in its first tenth of a second.
TRIP = {"axes": {"x": {"min_ferror_m": 1e-4, "ferror_m": 1e-3, "ferror_velocity_m_s": 0.1}}}
FAULT = re.compile(r"servo (\w+): following error (\S+) m exceeds the bound (\S+) m .* at t=(\S+) s")

pytestmark = pytest.mark.e2e


def test_following_error_trip_faults_naming_the_axis_on_the_engines_tick(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE, {"duration_s": 1.0, "servo": TRIP})
    with pytest.raises(EngineFault) as engine_fault:  # the run ends at the fault, keeping every tick before it
        run_engine(scenario)
    record = engine_fault.value.record
    assert record.summary["status"] == "faulted" and judge(record).status == "faulted"
    with pytest.raises(NodeDied) as graph_fault:
        run_graph(scenario, tmp_path, record=False)
    engine = FAULT.search(record.summary["faults"][0])
    graph = FAULT.search(str(graph_fault.value))
    assert engine is not None and graph is not None, (record.summary["faults"], str(graph_fault.value))
    assert record.joint_states.stamp_ns[-1] == round(float(engine.group(4)) * 1e9), "cut at the fault's tick"
    assert graph_fault.value.node == "servo_x"
    assert graph.group(1) == engine.group(1) == "x"
    assert graph.group(4) == engine.group(4) != "0.000000", "the same tick"
    assert float(graph.group(2)) == pytest.approx(float(engine.group(2)), abs=1e-9)
    assert abs(float(engine.group(2))) > float(engine.group(3))


def test_realtime_graph_at_a_deadline_it_cannot_keep_faults_on_the_late_share(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE, {"duration_s": 1.0, "sample_time_s": 1.0e-4, "mode": "realtime"})
    try:
        result = run_graph(scenario, tmp_path, record=False)
    except NodeDied as err:  # a stage that fell its queue behind may end the run first: not this test's case
        pytest.fail(f"expected the plant's late-share fault, got {err}")
    # late commands, or (a plant whose own ticks stretch sees each command within the stretched period) the
    # ticks' mean period: both say the machine does not hold T = 0.1 ms
    assert result.summary["status"] == "faulted"
    assert "max_late_share" in result.faults[0] or "max_period_ratio" in result.faults[0], result.faults


def test_plant_and_servos_report_every_second_of_run_time_into_the_bag(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE, {"duration_s": 1.5})
    result = run_graph(scenario, tmp_path, record=True)
    assert result.faults == [] and result.bag_path is not None
    _, statuses = read_statuses(result.bag_path)
    running = {s.name.rsplit("/", 1)[-1]: s.values for s in statuses if s.message == RUNNING}
    assert set(running) == {"plant", "servo_x", "servo_y"}, "one window (t = 1 s) per node in 1.5 s"
    for values in running.values():
        assert values["run_time_s"] == "1.000000" and values["ticks"] == "101"
        assert float(values["tick_rate_hz"]) > 0.0
    assert running["plant"]["estop_latched"] == "false" and running["plant"]["enabled"] == "true"
    assert 0.0 < float(running["servo_x"]["peak_following_error_m"]) < 1e-3
    assert 0.0 <= float(running["servo_x"]["saturated_share"]) <= 1.0


def test_estop_mid_run_latches_stops_the_axes_and_is_in_the_bag(tmp_path: Path) -> None:
    # A lockstep graph may run hundreds of ticks ahead of this process's probe (a starved test worker: 1000 ticks
    # once ended before the press at the probe's tick 41 arrived), so the run has 3000 ticks and the coast is judged
    # from the plant's latch tick. (In real time at T = 10 ms, four test workers on two cores made 43 % of commands
    # late.)
    scenario = load_scenario(CIRCLE, {"duration_s": 30.0})
    ns = "/cnc/estop_e2e"
    # extra_subscribers=1: every lockstep topic waits for one more reader, this probe's
    probed = {f"{ns}/reference": Reference, f"{ns}/servo/x/command": AxisCommand,
              f"{ns}/servo/y/command": AxisCommand}
    with TopicProbe(probed) as probe, ExitStack() as later:
        estop = probe.node.create_publisher(Bool, f"{ns}/estop", 10)
        sent: list[int] = []
        ticks: list[TopicProbe] = []

        def press_once_running(_: JointState) -> None:
            # from the probe's own joint_states callback: a polling loop may notice tick 40 after a fast run ended
            if not sent and len(ticks[0].received(f"{ns}/joint_states")) > 40:
                estop.publish(Bool(data=True))
                sent.append(len(ticks[0].received(f"{ns}/joint_states")))

        def read_ticks_once_the_estop_is_heard() -> None:
            # Plant and both servos latch, and the e-stop is volatile: none may miss it. The plant starts only
            # once every reader of joint_states matched, so the extra reader comes once all three read the
            # e-stop (a 300-tick run under load once ended before they had).
            if not ticks and estop.get_subscription_count() >= 3:
                ticks.append(later.enter_context(TopicProbe({f"{ns}/joint_states": JointState}, name="ticks")))
                ticks[0].watch(f"{ns}/joint_states", press_once_running)

        result = run_graph(scenario, tmp_path, record=True, extra_subscribers=1, namespace=ns,
                           on_poll=read_ticks_once_the_estop_is_heard)
    assert sent and result.faults == [] and result.summary["estop_latches"] == 1
    _, verdict = judge_bag(result.bag_path)
    assert verdict.status == "faulted" and "e-stop latched 1 time" in verdict.describe(), verdict.describe()
    _, statuses = read_statuses(result.bag_path)
    latched = {s.name.rsplit("/", 1)[-1]: s for s in statuses if s.message.startswith("e-stop latched")}
    assert set(latched) == {"plant", "servo_x", "servo_y"}, "each latch once (the servos freeze their laws)"
    cause = re.search(rf"{ns}/estop true at t=(\S+) s", latched["plant"].message)
    assert cause is not None, latched["plant"].message
    plant = [s for s in statuses if s.name.endswith("/plant")]
    latch = next(i for i, s in enumerate(plant) if s.message.startswith("e-stop latched"))
    after = [s.values for s in plant[latch:] if s.message == RUNNING]
    assert after and all(v["estop_latched"] == "true" for v in after), "the latch holds to the end of the run"
    # The coast, judged in the bag from the plant's own latch tick, not from when this process pressed.
    states = read_bag(result.bag_path, commands=False).joint_states
    speeds = np.abs(states.velocity_m_s).max(axis=1)
    first = int(np.searchsorted(states.stamp_ns, round(float(cause.group(1)) * 1e9)))
    assert len(speeds) - first >= 100, f"the latch (t={cause.group(1)} s) leaves a second to coast"
    assert speeds[-20:].max() < 0.2 * speeds[first:first + 20].max(), "zero commands: the axes coast to rest"
