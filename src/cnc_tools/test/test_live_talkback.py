"""The viewer talks back to a paced engine run (live/talkback.py) through the protocol client: parameters set, read
back and refused with the servo node's reason; an override, a feed hold and an e-stop published."""
from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cnc_tools.analysis.verdict import judge
from cnc_tools.live.client import LiveClient, Received
from cnc_tools.live.options import engine_live
from cnc_tools.live.talkback import EngineTalkback
from cnc_tools.live.watch import live_args
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import EngineFault, run_engine
from cnc_tools.runs.engine_stages import Board
from cnc_tools.runs.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[3]
#: The override's follower ramps within the axis limits: 0.5 of 1200 mm/min at 250 mm/s² takes 40 ms (4 ticks).
OVERRIDE_TICKS = 8
#: What the servo node answers to ``gains.kp`` -1 (rclpy's range check of its descriptor), and so the engine.
KP_REFUSED = "parameter servo_x.gains.kp refused: Parameter gains.kp out of range Min: 0.0, Max: 1000000.0, value: -1.0"


class _Run:
    """An engine run on its own thread, its record or its error kept."""

    def __init__(self, scenario: Scenario, options: dict[str, Any]) -> None:
        self.record: RunRecord | None = None
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, args=(scenario, options), daemon=True)

    def wait(self) -> None:
        """Until the run ended (its record or its error kept)."""
        self.thread.join(60.0)
        assert not self.thread.is_alive(), "the run did not end within 60 s"

    def _run(self, scenario: Scenario, options: dict[str, Any]) -> None:
        try:
            self.record = run_engine(scenario, **options)
        except BaseException as err:  # handed to the test's thread
            self.error = err


@contextmanager
def talking(scenario: Scenario, rate: float) -> Iterator[tuple[LiveClient, _Run]]:
    """A paced engine run with --live (not started: ``run.thread.start()``) and a client connected to it; the
    client and the server are closed however the test ends."""
    with engine_live(live_args(rate), scenario) as live:
        client = LiveClient(live["on_tick"].feed.server.url)  # type: ignore[attr-defined]  # an EngineLive
        try:
            client.wait_channels(("/cnc/joint_states",))
            run = _Run(scenario, live)
            yield client, run
            run.wait()
        finally:
            client.close()


def statuses(client: LiveClient, text: str) -> list[str]:
    return [s["message"] for s in client.statuses if text in s["message"]]


def wait_for(client: LiveClient, done: Callable[[], bool], what: str, timeout_s: float = 30.0) -> None:
    client.collect(lambda _: done(), timeout_s)
    assert done(), f"no {what} within {timeout_s} s; statuses {client.statuses}, channels {sorted(client.channels)}"


def test_a_gain_set_from_the_viewer_retunes_the_law_and_an_out_of_range_one_keeps_its_value() -> None:
    scenario = load_scenario(ROOT / "scenarios" / "paper001_circle.yaml", {"duration_s": 0.15})
    with talking(scenario, rate=1.0) as (client, run):
        before = client.get_parameters([], "all")
        assert before["servo_x.gains.kp"] == 5.0 and "servo_y.gains.ki" in before
        refused = client.set_parameters({"servo_x.gains.kp": -1.0}, "bad")
        assert refused["servo_x.gains.kp"] == 5.0
        wait_for(client, lambda: bool(statuses(client, "kp refused")), "refusal status")
        assert statuses(client, "kp refused") == [KP_REFUSED]
        assert client.set_parameters({"servo_x.gains.kp": 8.0}, "good")["servo_x.gains.kp"] == 8.0
        run.thread.start()  # the change was accepted before tick 0: it applies from tick 1 on
        run.wait()
        assert client.get_parameters(["servo_x.gains.kp"], "after") == {"servo_x.gains.kp": 8.0}
    assert run.error is None and run.record is not None
    live = run.record.commands["x"].command
    unchanged = run_engine(scenario).commands["x"].command
    retuned = run_engine(load_scenario(ROOT / "scenarios" / "paper001_circle.yaml", {
        "duration_s": 0.15, "servo": {"law_params": {"kp": 8.0}}})).commands["x"].command
    assert live[0] == unchanged[0] and not np.array_equal(live, unchanged)
    np.testing.assert_allclose(live[1:], retuned[1:], rtol=1e-6, atol=1e-9 * np.max(np.abs(retuned)))


def _overrides(received: list[Received]) -> list[dict[str, Any]]:
    return [r.json() for r in received if r.topic == "/live/feed_override"]


def test_an_override_a_feed_hold_and_an_e_stop_published_from_the_viewer() -> None:
    scenario = load_scenario(ROOT / "scenarios" / "feed_hold_circle.yaml", {
        "duration_s": 3.0, "feed_override": {"schedule": []}})  # requests from the topic, not the schedule
    with talking(scenario, rate=2.0) as (client, run):
        client.subscribe(["/live/feed_override"])
        client.advertise("/cnc/feed_override", "cnc_contour_interfaces/msg/FeedOverride")
        client.advertise("/cnc/feed_hold", "std_msgs/msg/Bool")
        client.advertise("/cnc/estop", "std_msgs/msg/Bool")
        run.thread.start()
        wait_for(client, lambda: bool(_overrides(client.pending)), "override sample")
        client.socket.send(b'\x01' + (1).to_bytes(4, "little") + b'{"requested_ratio": NaN}')
        client.publish("/cnc/feed_override", {"requested_ratio": 1.5})
        wait_for(client, lambda: len(statuses(client, "feed override ratio")) == 2, "two refusals")
        assert statuses(client, "feed override ratio") == [
            f"/cnc/feed_override refused: feed override ratio must be finite and in [0, max_ratio = 1], got {v}; "
            "holding 1" for v in ("nan", "1.5")]
        client.publish("/cnc/feed_override", {"requested_ratio": 0.5})
        wait_for(client, lambda: any(m["applied_ratio"] == 0.5 for m in _overrides(client.pending)), "ratio 0.5")
        samples = _overrides(client.pending)
        asked = next(m["stamp_ns"] for m in samples if m["requested_ratio"] == 0.5)
        reached = next(m["stamp_ns"] for m in samples if m["applied_ratio"] == 0.5)
        assert all(m["applied_ratio"] == 1.0 for m in samples if m["stamp_ns"] < asked)  # nothing before the ask
        assert reached - asked <= OVERRIDE_TICKS * 10_000_000, (asked, reached)
        client.publish("/cnc/feed_hold", {"data": True})
        wait_for(client, lambda: _overrides(client.pending)[-1]["applied_ratio"] == 0.0, "feed hold")
        assert _overrides(client.pending)[-1]["requested_ratio"] == 0.0
        client.publish("/cnc/estop", {"data": True})
    assert isinstance(run.error, EngineFault), run.error
    record = run.error.record
    stopped_s = record.joint_states.stamp_ns[-1] * 1e-9
    assert stopped_s < 2.9
    verdict = judge(record)
    assert verdict.status == "faulted"
    assert any(reason.startswith("e-stop from the live viewer (/cnc/estop true) at t = ") for reason in verdict.reasons)


@pytest.mark.parametrize(("topic", "schema", "payload", "reason"), [
    ("/cnc/enable", "std_msgs/msg/Bool", {"data": False}, "an engine run has no axis enable"),
    ("/cnc/estop", "std_msgs/msg/Bool", {"data": "yes"}, "data must be true or false, got 'yes'"),
    ("/cnc/feed_override", "cnc_contour_interfaces/msg/FeedOverride", {"requested_ratio": 0.5},
     "this run has no on-line feed override")])
def test_requests_the_run_cannot_take_are_refused_naming_why(topic: str, schema: str, payload: dict[str, Any],
                                                             reason: str) -> None:
    scenario = load_scenario(ROOT / "scenarios" / "paper001_circle.yaml", {"duration_s": 0.02})
    with talking(scenario, rate=1.0) as (client, run):
        client.advertise(topic, schema)
        client.publish(topic, payload)
        wait_for(client, lambda: bool(statuses(client, reason)), "refusal")
        run.thread.start()
    assert run.error is None


GRAPH_SERVO = {"axis": "x", "sample_time_s": 0.01, "law": "pid", "input_timeout_s": 30.0,
               "gains.kp": 2.4, "gains.ki": 10.0, "gains.kd": 0.067}


@contextmanager
def graph_server(scenario: Scenario, namespace: str) -> Iterator[LiveClient]:
    """graph_live's server for ``namespace`` (the live node on its own thread, the talkback onto the graph) and a
    client connected to it; all closed however the test ends."""
    from cnc_tools.live.decimate import WINDOW_NS
    from cnc_tools.live.feed import LiveFeed
    from cnc_tools.live.ros import LiveThread, RosBus
    from cnc_tools.live.server import LiveConfig, LiveServer
    from cnc_tools.live.talkback import GraphTalkback

    talkback = GraphTalkback(scenario)
    with LiveServer(LiveConfig(port=0), **talkback.server_options()) as server:
        talkback.attach(server)
        thread = LiveThread(LiveFeed(server, WINDOW_NS), namespace)
        try:
            talkback.bus = RosBus(thread.node)
            with LiveClient(server.url) as client:
                yield client
        finally:
            talkback.close()
            thread.close()


@pytest.mark.nodes
def test_a_graphs_gains_override_enable_and_e_stop_from_the_viewer() -> None:
    import functools
    import os

    from std_msgs.msg import Bool

    from cnc_contour_control.nodes.servo_node import ServoNode
    from cnc_contour_control.testing import InProcessNode, TopicProbe
    from cnc_contour_interfaces.msg import FeedOverride

    namespace = f"/talkback_{os.getpid()}"
    scenario = load_scenario(ROOT / "scenarios" / "feed_hold_circle.yaml", {"feed_override": {"schedule": []}})
    servo_x = functools.partial(ServoNode, cli_args=["--ros-args", "-r", "__node:=servo_x"])
    override, estop = f"{namespace}/feed_override", f"{namespace}/estop"
    with TopicProbe({override: FeedOverride, estop: Bool}) as probe, \
            InProcessNode(servo_x, GRAPH_SERVO, namespace) as servo, graph_server(scenario, namespace) as client:
        assert client.get_parameters(["servo_x.gains.kp"], "get") == {"servo_x.gains.kp": 2.4}
        assert client.set_parameters({"servo_x.gains.kp": -1.0}, "bad")["servo_x.gains.kp"] == 2.4
        assert servo.node.get_parameter("gains.kp").value == 2.4
        assert client.set_parameters({"servo_x.gains.kp": 3.0}, "good")["servo_x.gains.kp"] == 3.0
        assert servo.node.controller.law.config.kp == 3.0
        wait_for(client, lambda: bool(statuses(client, "kp refused")), "refusal status")
        assert statuses(client, "kp refused") == [KP_REFUSED]  # the servo node's own reason
        for topic, schema in (("/cnc/feed_override", "cnc_contour_interfaces/msg/FeedOverride"),
                              ("/cnc/enable", "std_msgs/msg/Bool"), ("/cnc/estop", "std_msgs/msg/Bool")):
            client.advertise(topic, schema)
        client.publish("/cnc/feed_override", {"requested_ratio": float("nan")})
        client.publish("/cnc/feed_override", {"requested_ratio": 0.5})
        wait_for(client, lambda: bool(probe.received(override)), "the override")
        assert [m.requested_ratio for m in probe.received(override)] == [0.5]
        wait_for(client, lambda: bool(statuses(client, "got nan")), "NaN refused")
        assert statuses(client, "got nan") == ["/cnc/feed_override refused: feed override ratio must be finite and "
                                               "in [0, max_ratio = 1], got nan; holding 1"]
        client.publish("/cnc/enable", {"data": False})
        probe.wait_for(lambda: not servo.node.latch.enabled, 10.0, "the servo disabled")
        client.publish("/cnc/estop", {"data": True})
        probe.wait_for(lambda: servo.node.latch.latched, 10.0, "the servo's latch")
        probe.wait_for(lambda: [m.data for m in probe.received(estop)] == [True], 10.0, "the e-stop, once")
        client.publish("/cnc/enable", {"data": True})
        wait_for(client, lambda: bool(statuses(client, "/cnc/enable refused")), "enable refused while latched")
        assert f"{namespace}/servo_x/enable: " in statuses(client, "/cnc/enable refused")[0]


def test_the_engines_range_refusal_is_rclpys_word_for_word() -> None:
    import rclpy
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    from cnc_tools.live.talkback import range_refusal

    context = Context()
    rclpy.init(context=context)
    try:
        node = Node("range_words", context=context)
        node.declare_parameter("eta", 0.5, ParameterDescriptor(floating_point_range=[
            FloatingPointRange(from_value=0.0, to_value=1000.0)]))
        node.declare_parameter("units", 5, ParameterDescriptor(integer_range=[
            IntegerRange(from_value=1, to_value=1000)]))
        for name, value in [("eta", -1.0), ("eta", math.nan), ("eta", math.inf), ("eta", 1000.0 * (1 + 1e-7)),
                            ("eta", 2000.0), ("eta", 3.0), ("units", 0), ("units", 1000), ("units", 1001)]:
            result = node.set_parameters([Parameter(name, value=value)])[0]
            low, high = (0.0, 1000.0) if name == "eta" else (1, 1000)
            assert range_refusal(name, low, high, value) == (None if result.successful else result.reason), value
        node.destroy_node()
    finally:
        context.try_shutdown()


def test_the_learning_rate_is_refused_out_of_its_range_and_reaches_the_compensator_at_the_next_tick() -> None:
    from foxglove.websocket import Parameter

    from cnc_tools.live.talkback import LEARNING_RATE
    from cnc_tools.runs.engine_cross_axis import CompensatorStage

    scenario = load_scenario(ROOT / "scenarios" / "paper001" / "paper000_circle_nn.yaml", {"duration_s": 0.05})
    talkback = EngineTalkback(scenario)
    stage = CompensatorStage(scenario, scenario.pipeline(), np.arange(50, dtype=np.int64))
    eta = stage.compensator.config.eta  # type: ignore[attr-defined]  # the neural compensator's
    assert talkback.values[LEARNING_RATE] == eta
    answer = talkback.on_set_parameters(None, [Parameter(LEARNING_RATE, value=2000.0)])  # type: ignore[arg-type]  # the client is not read
    assert {p.name: p.get_value() for p in answer}[LEARNING_RATE] == eta and not talkback.pending
    talkback.on_set_parameters(None, [Parameter(LEARNING_RATE, value=eta / 10)])  # type: ignore[arg-type]  # as above
    talkback.apply(Board(0.001), [stage])
    assert stage.compensator.config.eta == eta / 10  # type: ignore[attr-defined]  # as above


@pytest.mark.nodes
def test_a_graphs_learning_rate_from_the_viewer_reaches_the_compensator_node() -> None:
    import os

    from cnc_contour_control.nodes.compensator_node import CompensatorNode
    from cnc_contour_control.testing import InProcessNode

    namespace = f"/talkback_nn_{os.getpid()}"
    scenario = load_scenario(ROOT / "scenarios" / "paper001" / "paper000_circle_nn.yaml")
    assert scenario.compensator is not None
    params = {"axes": ["x", "y"], "sample_time_s": 0.01, "method": "neural", "input_timeout_s": 30.0,
              "params.eta": scenario.compensator.params["eta"]}  # the node as the run's graph starts it
    with InProcessNode(CompensatorNode, params, namespace) as node, graph_server(scenario, namespace) as client:
        eta = node.node.compensator.config.eta
        assert client.get_parameters(["compensator.params.eta"], "get") == {"compensator.params.eta": eta}
        assert client.set_parameters({"compensator.params.eta": 2000.0}, "bad")["compensator.params.eta"] == eta
        assert client.set_parameters({"compensator.params.eta": eta / 10}, "good")["compensator.params.eta"] == eta / 10
        assert node.node.compensator.config.eta == eta / 10
        wait_for(client, lambda: bool(statuses(client, "eta refused")), "refusal status")
        assert statuses(client, "eta refused") == ["parameter compensator.params.eta refused: Parameter params.eta out "
                                                   "of range Min: 0.0, Max: 1000.0, value: 2000.0"]
