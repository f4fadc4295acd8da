"""Tier 2: the lifecycle manager configures, then activates, managed nodes, and faults naming a refusal."""
from __future__ import annotations

import uuid

import pytest
from diagnostic_msgs.msg import DiagnosticArray

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_tools.nodes.lifecycle_manager import LifecycleManagerNode, TransitionPlan

NS = "/lifecycle_manager_test"
ACTION_MODE = {"axes": ["x", "y"], "program_source": "action", "program_file": "", "managed": True}


@pytest.fixture(autouse=True)
def _fresh_namespace(monkeypatch: pytest.MonkeyPatch) -> None:
    """A namespace of each test's own: no stale service of an earlier test's node (same name) can take a request."""
    monkeypatch.setitem(globals(), "NS", f"/lifecycle_manager_{uuid.uuid4().hex[:8]}")


def test_the_plan_configures_every_node_before_activating_any() -> None:
    plan = TransitionPlan(("interpolator", "servo_x", "plant"))
    labels = [(name, label) for name, _, label in plan.steps]
    assert labels == [("interpolator", "configure"), ("servo_x", "configure"), ("plant", "configure"),
                      ("interpolator", "activate"), ("servo_x", "activate"), ("plant", "activate")]
    with pytest.raises(ConfigError, match="node_names"):
        TransitionPlan(("plant", "plant"))
    with pytest.raises(ConfigError, match="node_names"):
        TransitionPlan(())


@pytest.mark.nodes
def test_the_manager_brings_a_managed_interpolator_to_active() -> None:
    with TopicProbe({"/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(InterpolatorNode, ACTION_MODE, namespace=NS) as interpolator, \
            InProcessNode(LifecycleManagerNode, {"node_names": ["interpolator"]}, namespace=NS) as manager:
        probe.wait_for(lambda: interpolator.node.armed, 30.0, "the interpolator to be active")
        probe.wait_for(lambda: manager.node.plan.finished, 10.0, "the manager's plan to finish")
        assert manager.node.fault_message is None
        assert interpolator.node._state_machine.current_state[1] == "active"


@pytest.mark.nodes
def test_a_refused_configure_is_the_managers_fault_naming_the_node() -> None:
    with TopicProbe({"/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(InterpolatorNode, {**ACTION_MODE, "program_source": "tape"}, namespace=NS) as interpolator, \
            InProcessNode(LifecycleManagerNode, {"node_names": ["interpolator"]}, namespace=NS) as manager:
        probe.wait_for(lambda: manager.node.fault_message is not None, 30.0, "the manager's fault")
    assert manager.node.fault_message == "lifecycle_manager: configure interpolator refused " \
                                         "(see interpolator's log and /diagnostics)"
    assert "tape" in str(interpolator.node.configure_error), "the node's own reason"
    assert interpolator.node._state_machine.current_state[1] == "unconfigured"
