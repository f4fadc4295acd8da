"""Tier 2: a managed node (rclpy.lifecycle) waits unconfigured, validates on configure, refuses wrong transitions."""
from __future__ import annotations

import uuid
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState

from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.testing import InProcessNode, TopicProbe

pytestmark = pytest.mark.nodes
NS = "/lifecycle_test"
ACTION_MODE = {"axes": ["x", "y"], "program_source": "action", "program_file": "", "managed": True}


@pytest.fixture(autouse=True)
def _fresh_namespace(monkeypatch: pytest.MonkeyPatch) -> None:
    """A namespace of each test's own: no stale service of an earlier test's node (same name) can take a request."""
    monkeypatch.setitem(globals(), "NS", f"/lifecycle_{uuid.uuid4().hex[:8]}")


def _call(probe: TopicProbe, srv_type: type, name: str, request: Any) -> Any:
    return probe.call(srv_type, f"{NS}/interpolator/{name}", request)


def _state(probe: TopicProbe) -> str:
    return _call(probe, GetState, "get_state", GetState.Request()).current_state.label


def _change(probe: TopicProbe, transition_id: int) -> bool:
    return bool(_call(probe, ChangeState, "change_state",
                      ChangeState.Request(transition=Transition(id=transition_id))).success)


def test_a_managed_interpolator_builds_on_configure_and_arms_on_activate_only_in_order() -> None:
    with TopicProbe({"/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(InterpolatorNode, ACTION_MODE, namespace=NS) as node:
        assert _state(probe) == "unconfigured"
        assert probe.node.count_publishers(f"{NS}/reference") == 0, "nothing built before configure"
        assert not _change(probe, Transition.TRANSITION_ACTIVATE), "activate while unconfigured"
        assert _state(probe) == "unconfigured" and not node.node.finished
        assert _change(probe, Transition.TRANSITION_CONFIGURE)
        assert _state(probe) == "inactive" and not node.node.armed
        probe.wait_for(lambda: probe.node.count_publishers(f"{NS}/reference") == 1, 10.0, "the reference publisher")
        assert _change(probe, Transition.TRANSITION_ACTIVATE)
        assert _state(probe) == "active" and node.node.armed
        assert not _change(probe, Transition.TRANSITION_CONFIGURE), "configure while active"
        assert _change(probe, Transition.TRANSITION_DEACTIVATE) and not node.node.armed
        assert not _change(probe, Transition.TRANSITION_CLEANUP), "cleanup is refused (read-only parameters)"
        assert _state(probe) == "inactive"
        assert _change(probe, Transition.TRANSITION_INACTIVE_SHUTDOWN)
        probe.wait_for(lambda: node.node.finished, 10.0, "the node to end on shutdown")


def test_configure_with_a_bad_parameter_is_refused_naming_it_and_the_node_stays_unconfigured() -> None:
    with TopicProbe({"/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(InterpolatorNode, {**ACTION_MODE, "program_source": "tape"}, namespace=NS) as node:
        assert _state(probe) == "unconfigured"
        probe.wait_for(lambda: node.node.status_publisher.get_subscription_count() > 0, 10.0, "the probe's match")
        assert not _change(probe, Transition.TRANSITION_CONFIGURE)
        assert _state(probe) == "unconfigured" and not node.node.finished
        errors = lambda: [s for a in probe.received("/diagnostics") for s in a.status
                          if s.level == DiagnosticStatus.ERROR]
        probe.wait_for(errors, 10.0, "the refusal on /diagnostics")
    message = errors()[0].message
    assert message.startswith("configure refused: ") and "program_source" in message and "tape" in message, message


def test_an_unmanaged_node_with_a_bad_parameter_still_fails_at_start() -> None:
    from cnc_contour_control.core.errors import CncError

    with pytest.raises(CncError, match="program_source"):
        with InProcessNode(InterpolatorNode, {**ACTION_MODE, "managed": False, "program_source": "tape"},
                           namespace=NS):
            pass


def test_a_fixed_profile_refuses_deactivate_it_cannot_stop_on_the_path(tmp_path: Path) -> None:
    program = tmp_path / "line.ngc"
    program.write_text("G1 X10 F600\nM2\n")
    params = {"axes": ["x", "y"], "program_file": str(program), "managed": True}
    with TopicProbe({"/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(InterpolatorNode, params, namespace=NS) as node:
        assert _change(probe, Transition.TRANSITION_CONFIGURE) and _change(probe, Transition.TRANSITION_ACTIVATE)
        assert not _change(probe, Transition.TRANSITION_DEACTIVATE)
        assert _state(probe) == "active" and node.node.armed
