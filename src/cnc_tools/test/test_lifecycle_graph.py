"""Tier 2: the lifecycle in a running graph (plant, servos and an action-mode interpolator in-process, as the runner
starts paper 000's circle): a servo cleaned up, given new gains, configured and activated between two programs;
one node shut down faults the run naming it while the others stay up and re-armable."""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from sensor_msgs.msg import JointState

from cnc_contour_control.testing import ThreadSafeActionClient, TopicProbe
from cnc_contour_interfaces.action import RunProgram
from cnc_tools.runs.scenario import load_scenario
from cnc_tools.testing import own_domain, start_graph_in_process

pytestmark = pytest.mark.nodes


@pytest.fixture(autouse=True)
def _own_domain() -> Iterator[int]:
    """Each test's in-process graph in a domain of its own (:func:`cnc_tools.testing.own_domain`)."""
    with own_domain() as domain:
        yield domain


SCENARIO = Path(__file__).resolve().parents[3] / "scenarios" / "paper000_circle_high.yaml"


def change(probe: TopicProbe, node: str, transition_id: int) -> bool:
    return bool(probe.call(ChangeState, f"/cnc/{node}/change_state",
                           ChangeState.Request(transition=Transition(id=transition_id))).success)


def start_graph(stack: ExitStack, tmp_path: Path) -> tuple[dict[str, Any], TopicProbe]:
    """The graph's nodes by name, and a probe of joint_states and /diagnostics once the plant ticks."""
    nodes = start_graph_in_process(stack, load_scenario(SCENARIO, {}), tmp_path)
    probe = stack.enter_context(TopicProbe({"/cnc/joint_states": JointState, "/diagnostics": DiagnosticArray}))
    probe.wait_for(lambda: len(probe.received("/cnc/joint_states")) > 10, 30.0, "the graph's ticks")
    return nodes, probe


def errors(probe: TopicProbe) -> list[Any]:
    return [s for a in probe.received("/diagnostics") for s in a.status if s.level == DiagnosticStatus.ERROR]


def run_program(probe: TopicProbe, client: ThreadSafeActionClient, gcode: str) -> Any:
    probe.wait_for(client.server_is_ready, 20.0, "the RunProgram server")
    sent = client.send_goal_async(RunProgram.Goal(gcode=gcode))
    probe.wait_for(sent.done, 20.0, "the goal's answer")
    result = sent.result().get_result_async()
    probe.wait_for(result.done, 60.0, "the goal's result")
    return result.result().result


def test_cleanup_new_gains_configure_activate_and_a_second_program_runs(tmp_path: Path) -> None:
    """The plant paused (deactivate: no tick waits), servo_x deactivated, cleaned up, kp set, configured, activated."""
    with ExitStack() as stack:
        nodes, probe = start_graph(stack, tmp_path)
        client = ThreadSafeActionClient(probe.node, RunProgram, "/cnc/run_program")
        first = run_program(probe, client, "G1 X1 F1200")
        assert change(probe, "plant", Transition.TRANSITION_DEACTIVATE)
        probe.wait_for(lambda: nodes["plant"]._tick_held, 10.0, "the plant to hold its next tick")
        for transition in (Transition.TRANSITION_DEACTIVATE, Transition.TRANSITION_CLEANUP):
            assert change(probe, "servo_x", transition), f"servo_x: transition {transition}"
        kp = ParameterMsg(name="gains.kp", value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=3.0))
        assert probe.call(SetParameters, "/cnc/servo_x/set_parameters",
                          SetParameters.Request(parameters=[kp])).results[0].successful
        for node, transition in (("servo_x", Transition.TRANSITION_CONFIGURE),
                                 ("servo_x", Transition.TRANSITION_ACTIVATE),
                                 ("plant", Transition.TRANSITION_ACTIVATE)):
            assert change(probe, node, transition), f"{node}: transition {transition}"
        second = run_program(probe, client, "G1 X0 F1200")
        got = probe.call(GetParameters, "/cnc/servo_x/get_parameters", GetParameters.Request(names=["gains.kp"]))
        assert not any(n.finished for n in nodes.values()) and errors(probe) == [], errors(probe)
        assert nodes["servo_x"].controller.config.law_params["kp"] == 3.0, "the law built with the new gain"
    assert first.outcome == RunProgram.Result.COMPLETED, first.reason
    assert second.outcome == RunProgram.Result.COMPLETED, second.reason
    assert got.values[0].double_value == 3.0


def test_a_servo_shut_down_faults_the_run_naming_it_and_the_others_stay_up_and_rearm(tmp_path: Path) -> None:
    with ExitStack() as stack:
        nodes, probe = start_graph(stack, tmp_path)
        assert change(probe, "servo_x", Transition.TRANSITION_ACTIVE_SHUTDOWN)
        probe.wait_for(lambda: errors(probe), 10.0, "the plant's fault")
        probe.wait_for(lambda: nodes["plant"].finished, 10.0, "the plant to end")
        assert nodes["servo_x"].finished
        assert not nodes["servo_y"].finished and not nodes["interpolator"].finished, "the others stay up"
        for node in ("servo_y", "interpolator"):
            for transition in (Transition.TRANSITION_DEACTIVATE, Transition.TRANSITION_CLEANUP,
                               Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE):
                assert change(probe, node, transition), f"{node}: transition {transition}"
        assert not nodes["servo_y"].finished and not nodes["interpolator"].finished
    fault = errors(probe)[0]
    assert fault.name == "/cnc/plant", fault
    assert fault.message.startswith("plant: /cnc/servo_x left the graph: /cnc/servo/x/command has 0 publishers"), fault
