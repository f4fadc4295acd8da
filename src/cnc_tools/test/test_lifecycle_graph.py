"""Tier 2: one node of a running graph shut down (lifecycle ``shutdown``) faults the run naming it; the others stay
up and re-armable (deactivate, cleanup, configure, activate). Plant, servos and an action-mode interpolator
in-process, as the runner starts paper 000's circle."""
from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from sensor_msgs.msg import JointState

from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_plant_sim.nodes.plant_node import PlantNode
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import load_scenario

pytestmark = pytest.mark.nodes
SCENARIO = Path(__file__).resolve().parents[3] / "scenarios" / "paper000_circle_high.yaml"
NODE_CLASSES = {"plant": PlantNode, "interpolator": InterpolatorNode, "servo": ServoNode}
OVERRIDES: dict[str, dict[str, Any]] = {"plant": {"duration_s": 1.0e5, "summary_file": ""},
             "interpolator": {"program_source": "action", "program_file": ""}}


def flat(mapping: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in mapping.items():
        if isinstance(value, dict):
            out.update(flat(value, f"{prefix}{key}."))
        elif not (isinstance(value, (list, tuple)) and not value):
            out[f"{prefix}{key}"] = value
    return out


def change(probe: TopicProbe, node: str, transition_id: int) -> bool:
    return bool(probe.call(ChangeState, f"/cnc/{node}/change_state",
                           ChangeState.Request(transition=Transition(id=transition_id))).success)


def test_a_servo_shut_down_faults_the_run_naming_it_and_the_others_stay_up_and_rearm(tmp_path: Path) -> None:
    scenario = load_scenario(SCENARIO, {})
    with ExitStack() as stack:
        nodes = {}
        for spec in graph_specs(scenario, tmp_path, extra_subscribers=0):
            params = {**flat(dict(spec.parameters)), **OVERRIDES.get(spec.name, {})}

            def factory(node_class: type = NODE_CLASSES[spec.executable], name: str = spec.name,
                        **kwargs: Any) -> Any:
                return node_class(cli_args=["--ros-args", "-r", f"__node:={name}"], **kwargs)

            nodes[spec.name] = stack.enter_context(InProcessNode(factory, params)).node
        probe = stack.enter_context(TopicProbe({"/cnc/joint_states": JointState, "/diagnostics": DiagnosticArray}))
        probe.wait_for(lambda: len(probe.received("/cnc/joint_states")) > 10, 30.0, "the graph's ticks")
        assert change(probe, "servo_x", Transition.TRANSITION_ACTIVE_SHUTDOWN)

        def errors() -> list[Any]:
            return [s for a in probe.received("/diagnostics") for s in a.status if s.level == DiagnosticStatus.ERROR]

        probe.wait_for(errors, 10.0, "the plant's fault")
        probe.wait_for(lambda: nodes["plant"].finished, 10.0, "the plant to end")
        assert nodes["servo_x"].finished
        assert not nodes["servo_y"].finished and not nodes["interpolator"].finished, "the others stay up"
        for node in ("servo_y", "interpolator"):
            for transition in (Transition.TRANSITION_DEACTIVATE, Transition.TRANSITION_CLEANUP,
                               Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE):
                assert change(probe, node, transition), f"{node}: transition {transition}"
        assert not nodes["servo_y"].finished and not nodes["interpolator"].finished
    fault = errors()[0]
    assert fault.name == "/cnc/plant", fault
    assert fault.message.startswith("plant: /cnc/servo_x left the graph: /cnc/servo/x/command has 0 publishers"), fault
