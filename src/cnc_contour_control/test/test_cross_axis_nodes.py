"""Tier 2: the estimator and compensator nodes in-process with real rclpy and DDS (loopback), real messages."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.estimators import make_estimator
from cnc_contour_control.motion.program_file import read_program_file
from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.nodes.compensator_node import CompensatorNode
from cnc_contour_control.nodes.estimator_node import EstimatorNode
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import Compensation, ContourError, Reference

pytestmark = pytest.mark.nodes
ROOT = Path(__file__).resolve().parents[3]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
ESTIMATOR_PARAMS = {"axes": ["x", "y"], "program_file": str(CIRCLE), "sample_time_s": 0.01, "method": "window",
                    "input_timeout_s": 30.0}
COMPENSATOR_PARAMS = {"axes": ["x", "y"], "sample_time_s": 0.01, "method": "neural", "input_timeout_s": 30.0}
PROBE = {"/cnc/contour_error": ContourError, "/cnc/compensation": Compensation, "/diagnostics": DiagnosticArray}


def _header(stamp_ns: int) -> Header:
    return Header(stamp=ns_to_stamp(stamp_ns), frame_id="machine")


def joint_state(stamp_ns: int, position_m: list[float]) -> JointState:
    return JointState(header=_header(stamp_ns), name=["x", "y"], position=position_m, velocity=[0.0, 0.0])


def reference(stamp_ns: int, position_m: list[float]) -> Reference:
    return Reference(header=_header(stamp_ns), axis_names=["x", "y"], position_m=position_m,
                     velocity_m_s=[0.0, 0.0], acceleration_m_s2=[0.0, 0.0])


def contour_error(stamp_ns: int, error_m: float, angle_rad: float = 0.0) -> ContourError:
    return ContourError(header=_header(stamp_ns), axis_names=["x", "y"], contour_error_m=error_m,
                        tracking_error_m=[0.0, error_m], angle_rad=angle_rad, point_a_m=[0.0, 0.0],
                        point_b_m=[0.0, 0.0])


def _publishers(probe: TopicProbe, topics: dict[str, type]) -> dict[str, object]:
    pubs = {name: probe.publisher(msg_type, f"/cnc/{name}") for name, msg_type in topics.items()}
    probe.wait_for(lambda: all(p.get_subscription_count() for p in pubs.values()), 10.0, "the node's readers")
    return pubs


def _ticks(k: int) -> tuple[int, list[float], list[float]]:
    """Tick k of a small circle-like motion: stamp, reference, position (lagging)."""
    angle = 0.05 * k
    ref = [0.01 * math.sin(angle), 0.01 * (1.0 - math.cos(angle))]
    return k * 10_000_000, ref, [0.999 * ref[0], 0.999 * ref[1] + 2e-6]


def test_estimator_node_publishes_what_the_core_estimates() -> None:
    core = make_estimator("window", {}, read_program_file(str(CIRCLE), ("x", "y")))
    with TopicProbe(PROBE) as probe, InProcessNode(EstimatorNode, ESTIMATOR_PARAMS):
        pubs = _publishers(probe, {"joint_states": JointState, "reference": Reference})
        expected = []
        for k in range(8):
            stamp, ref, pos = _ticks(k)
            pubs["reference"].publish(reference(stamp, ref))
            pubs["joint_states"].publish(joint_state(stamp, pos))
            expected.append(core.step(ref, pos).contour_error_m)
        probe.wait_for(lambda: len(probe.received("/cnc/contour_error")) == 8, 10.0, "8 estimates")
    received = probe.received("/cnc/contour_error")
    assert [m.contour_error_m for m in received] == expected
    assert any(e != 0.0 for e in expected), "the motion gives a contour error"
    assert all(m.method == "window" and m.window_size >= 1 for m in received)


def test_estimator_node_refuses_a_non_finite_position_and_reports_it() -> None:
    with TopicProbe(PROBE) as probe, InProcessNode(EstimatorNode, ESTIMATOR_PARAMS) as estimator:
        pubs = _publishers(probe, {"joint_states": JointState, "reference": Reference})
        pubs["reference"].publish(reference(0, [0.0, 0.0]))
        pubs["joint_states"].publish(joint_state(0, [math.nan, 0.0]))
        probe.wait_for(lambda: probe.received("/diagnostics"), 10.0, "a diagnostic")
        assert estimator.node.finished
    status = probe.received("/diagnostics")[0].status[0]
    assert status.level == DiagnosticStatus.ERROR and "joint_states.position" in status.message
    assert probe.received("/cnc/contour_error") == []


def test_compensator_node_refuses_a_non_finite_contour_error_before_the_network_sees_it() -> None:
    with TopicProbe(PROBE) as probe, InProcessNode(CompensatorNode, COMPENSATOR_PARAMS) as node:
        before = node.node.compensator.input_weights.copy()
        pubs = _publishers(probe, {"joint_states": JointState, "reference": Reference,
                                   "contour_error": ContourError})
        pubs["reference"].publish(reference(0, [0.0, 0.0]))
        pubs["joint_states"].publish(joint_state(0, [0.0, 0.0]))
        pubs["contour_error"].publish(contour_error(0, math.inf))
        probe.wait_for(lambda: probe.received("/diagnostics"), 10.0, "a diagnostic")
        np.testing.assert_array_equal(node.node.compensator.input_weights, before)
    status = probe.received("/diagnostics")[0].status[0]
    assert status.level == DiagnosticStatus.ERROR and "contour_error" in status.message
    assert "non-finite" in status.message
    assert probe.received("/cnc/compensation") == []


def test_compensator_node_stops_diverging_learning_and_zeroes_its_output() -> None:
    params = {**COMPENSATOR_PARAMS, "params.eta": 1.0e3, "params.output_limit": 1.0, "params.pinned_ticks": 3}
    with TopicProbe(PROBE) as probe, InProcessNode(CompensatorNode, params) as node:
        pubs = _publishers(probe, {"joint_states": JointState, "reference": Reference,
                                   "contour_error": ContourError})
        for k in range(40):
            stamp, ref, pos = _ticks(k)
            for name, msg in (("reference", reference(stamp, ref)), ("joint_states", joint_state(stamp, pos)),
                              ("contour_error", contour_error(stamp, 1e-3, 0.05 * k))):
                pubs[name].publish(msg)
        probe.wait_for(lambda: len(probe.received("/cnc/compensation")) == 40, 10.0, "40 compensations")
        fault = node.node.compensator.fault

        def guard_errors() -> list[DiagnosticStatus]:
            return [s for a in probe.received("/diagnostics") for s in a.status if s.level == DiagnosticStatus.ERROR]

        probe.wait_for(guard_errors, 10.0, "the guard's ERROR status")
        errors = guard_errors()
    assert fault is not None, "the guard tripped"
    received = probe.received("/cnc/compensation")
    stopped = [k for k, m in enumerate(received) if not m.learning]
    assert stopped and all(list(m.correction) == [0.0, 0.0] for m in received[stopped[0]:])
    assert "compensator" in errors[0].message and "learning stopped" in errors[0].message, \
        "an ERROR, so the run's verdict is faulted"


@pytest.mark.parametrize(("content", "words"), [
    (b"not a numeric array file", ["bad.npz"]),
    (None, ["bad.npz"]),
], ids=["not npz", "wrong shape"])
def test_compensator_node_refuses_a_bad_state_file_naming_it(tmp_path: Path, content: bytes | None,
                                                             words: list[str]) -> None:
    path = tmp_path / "bad.npz"
    if content is None:
        np.savez(path, V=np.zeros((3, 3)), W=np.zeros((2, 4)))
    else:
        path.write_bytes(content)
    with pytest.raises(CncError) as err:
        InProcessNode(CompensatorNode, {**COMPENSATOR_PARAMS, "state_in": str(path)})
    assert all(w in str(err.value) for w in words), str(err.value)


def test_a_running_compensator_refuses_a_method_parameter_it_would_not_take() -> None:
    """Only freeze and the network's learning rate change while it runs; any other params.* is refused, named."""
    from rclpy.parameter import Parameter

    with InProcessNode(CompensatorNode, COMPENSATOR_PARAMS) as node:
        eta = node.node.compensator.config.eta
        refused = node.node.set_parameters([Parameter("params.output_limit", value=0.5)])[0]
        assert not refused.successful and "params.output_limit" in refused.reason and "params.eta" in refused.reason
        assert node.node.get_parameter("params.output_limit").value != 0.5
        taken = node.node.set_parameters([Parameter("params.eta", value=eta / 2)])[0]
        assert taken.successful and node.node.compensator.config.eta == eta / 2
