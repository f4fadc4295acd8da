"""Tier 2: a managed node (rclpy.lifecycle) waits unconfigured, validates on configure, refuses wrong transitions."""
from __future__ import annotations

import uuid
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from cnc_contour_control.nodes.common import ns_to_stamp, stamp_to_ns
from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.testing import InProcessNode, ThreadSafeActionClient, TopicProbe
from cnc_contour_interfaces.action import RunProgram
from cnc_contour_interfaces.msg import Reference

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
        assert _change(probe, Transition.TRANSITION_CLEANUP)
        assert _state(probe) == "unconfigured" and not node.node.finished
        probe.wait_for(lambda: probe.node.count_publishers(f"{NS}/reference") == 0, 10.0, "cleanup's end of reference")
        assert _change(probe, Transition.TRANSITION_CONFIGURE), "configured anew after cleanup"
        probe.wait_for(lambda: probe.node.count_publishers(f"{NS}/reference") == 1, 10.0, "one reference publisher")
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


def _set_string(probe: TopicProbe, name: str, value: str) -> bool:
    request = SetParameters.Request(parameters=[ParameterMsg(name=name, value=ParameterValue(
        type=ParameterType.PARAMETER_STRING, string_value=value))])
    return bool(_call(probe, SetParameters, "set_parameters", request).results[0].successful)


def test_cleanup_lets_new_parameters_be_configured_and_a_second_program_runs_with_them() -> None:
    """configure, activate, goal 1; deactivate, cleanup, a read-only parameter set anew, configure, activate, goal 2.

    The test is the machine (each joint state at the last reference, as test_program_goals_node's); the second
    configuration is a new run, its ticks from t = 0 again.
    """
    params = {**ACTION_MODE, "settle_time_s": 0.02, "feedback_period_s": 0.05}
    with TopicProbe({f"{NS}/reference": Reference}) as probe, \
            InProcessNode(InterpolatorNode, params, namespace=NS) as node:
        client = ThreadSafeActionClient(probe.node, RunProgram, f"{NS}/run_program")
        joints = probe.publisher(JointState, f"{NS}/joint_states")
        position_m, k = [0.0, 0.0], 0

        def tick() -> None:
            nonlocal position_m, k
            joints.publish(JointState(header=Header(stamp=ns_to_stamp(k * 10_000_000)), name=["x", "y"],
                                      position=list(position_m), velocity=[0.0, 0.0]))

            def refs() -> list[Any]:
                return [m for m in probe.received(f"{NS}/reference")
                        if stamp_to_ns(m.header.stamp) == k * 10_000_000 and m.header.frame_id == frame]

            probe.wait_for(lambda: bool(refs()), 20.0, f"reference {k} in frame {frame}")
            position_m, k = list(refs()[-1].position_m), k + 1

        def until(future: Any) -> Any:
            for _ in range(3000):
                if future.done():
                    return future.result()
                tick()
            raise AssertionError("no answer within 3000 ticks")

        def run(gcode: str) -> Any:
            probe.wait_for(client.server_is_ready, 20.0, "the RunProgram server")
            probe.wait_for(lambda: joints.get_subscription_count() > 0, 20.0, "the joint_states reader")
            tick()  # the node holds a joint state before the goal comes (a goal first is REJECTED: no joint_states yet)
            handle = until(client.send_goal_async(RunProgram.Goal(gcode=gcode)))
            return until(handle.get_result_async()).result

        frame = "machine"
        assert _change(probe, Transition.TRANSITION_CONFIGURE) and _change(probe, Transition.TRANSITION_ACTIVATE)
        first = run("G1 X1 F1200")
        assert not _set_string(probe, "frame_id", "table"), "read-only while configured"
        assert _change(probe, Transition.TRANSITION_DEACTIVATE) and _change(probe, Transition.TRANSITION_CLEANUP)
        assert _state(probe) == "unconfigured"
        probe.wait_for(lambda: joints.get_subscription_count() == 0, 10.0, "cleanup's end of the joint_states reader")
        assert _set_string(probe, "frame_id", "table"), "writable while unconfigured"
        assert _change(probe, Transition.TRANSITION_CONFIGURE) and _change(probe, Transition.TRANSITION_ACTIVATE)
        assert not _set_string(probe, "frame_id", "shop"), "read-only again once configured"
        got = _call(probe, GetParameters, "get_parameters", GetParameters.Request(names=["frame_id"]))
        frame, k = "table", 0
        second = run("G1 X2 F1200")
        assert not node.node.finished
    assert first.outcome == RunProgram.Result.COMPLETED, first.reason
    assert second.outcome == RunProgram.Result.COMPLETED, second.reason
    assert got.values[0].string_value == "table" and position_m[0] == pytest.approx(2e-3, abs=1e-5)
    assert second.path_length_m == pytest.approx(1e-3, rel=1e-3), "the second run started where the first ended"
