"""Tier 3: a feed override schedule with a feed hold on the node graph; the recorded reference is the engine's."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.engine import run_engine, tick_count
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
FEED_HOLD = ROOT / "scenarios" / "feed_hold_circle.yaml"
pytestmark = pytest.mark.e2e


def test_feed_hold_graph_records_the_engines_reference(tmp_path: Path) -> None:
    scenario = load_scenario(FEED_HOLD)
    graph = run_scenario(scenario, "graph", tmp_path / "graph")
    engine = run_engine(scenario)
    assert graph.integrity.complete and graph.ticks == tick_count(scenario) == engine.ticks
    assert graph.reference is not None and engine.reference is not None
    np.testing.assert_array_equal(graph.reference.stamp_ns, engine.reference.stamp_ns)
    for name in ("position_m", "velocity_m_s", "acceleration_m_s2", "path_length_m", "feed_m_s",
                 "feed_override_ratio"):
        np.testing.assert_allclose(getattr(graph.reference, name), getattr(engine.reference, name),
                                   rtol=0.0, atol=1e-9, err_msg=name)
    np.testing.assert_allclose(graph.joint_states.position_m, engine.joint_states.position_m, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(graph.command_array(), engine.command_array(), rtol=0.0, atol=1e-9)
    ratio = graph.reference.feed_override_ratio
    assert ratio is not None and ratio.min() == 0.0 and ratio[-1] == 1.0, "the hold and the resume reached the wire"
    assert graph.reference.done[-1]


# ---------------------------------------------------------------- the interpolator node alone, real rclpy and DDS
NS = "/feed_override_node_test"
CIRCLE_PROGRAM = {"program": {"shape": "circle", "radius_mm": 10, "feed_mm_min": 1200}}


def _program_file(tmp_path: Path) -> Path:
    import yaml

    path = tmp_path / "program.yaml"
    path.write_text(yaml.safe_dump(CIRCLE_PROGRAM))
    return path


def _joint_state(stamp_ns: int):
    from sensor_msgs.msg import JointState

    from cnc_contour_control.nodes.common import ns_to_stamp

    msg = JointState(name=["x", "y"], position=[0.01, 0.0], velocity=[0.0, 0.0])
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


def _override(stamp_ns: int, ratio: float):
    from cnc_contour_control.nodes.common import ns_to_stamp
    from cnc_contour_interfaces.msg import FeedOverride

    msg = FeedOverride(requested_ratio=ratio, applied_ratio=ratio, quantum=0.0)
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


class _Rig:
    """A probe that drives one interpolator node tick by tick and reads its references."""

    def __init__(self, probe: object) -> None:
        from sensor_msgs.msg import JointState

        from cnc_contour_interfaces.msg import FeedOverride

        self.probe = probe
        self.joint_states = probe.publisher(JointState, f"{NS}/joint_states")  # type: ignore[attr-defined]  # probe: a TopicProbe
        self.overrides = probe.publisher(FeedOverride, f"{NS}/feed_override")  # type: ignore[attr-defined]  # probe: a TopicProbe

    def references(self) -> list:
        return self.probe.received(f"{NS}/reference")  # type: ignore[attr-defined]  # probe: a TopicProbe

    def wait_ready(self, with_override: bool = True) -> None:
        self.probe.wait_for(lambda: self.joint_states.get_subscription_count() > 0 and (  # type: ignore[attr-defined]  # probe: a TopicProbe
            not with_override or self.overrides.get_subscription_count() > 0), 15.0, "the interpolator's readers")

    def tick(self, k: int) -> object:
        """Send joint_states(k) and wait for reference(k)."""
        self.joint_states.publish(_joint_state(k * 10_000_000))
        self.probe.wait_for(lambda: len(self.references()) > k, 10.0, f"reference {k}")  # type: ignore[attr-defined]  # probe: a TopicProbe
        return self.references()[k]


def _node_parameters(tmp_path: Path, source: str, **extra: object) -> dict[str, object]:
    return {"program_file": str(_program_file(tmp_path)), "feed_override_source": source,
            "feed_override.max_ratio": 1.0, **extra}


def test_the_interpolator_node_follows_an_operators_feed_override_topic(tmp_path: Path) -> None:
    from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
    from cnc_contour_control.testing import InProcessNode, TopicProbe
    from cnc_contour_interfaces.msg import Reference

    with TopicProbe({f"{NS}/reference": Reference}) as probe, \
            InProcessNode(InterpolatorNode, _node_parameters(tmp_path, "topic", max_acceleration_m_s2=[0.25, 0.25]),
                          namespace=NS):
        rig = _Rig(probe)
        rig.wait_ready()
        for k in range(10):
            rig.tick(k)
        rig.overrides.publish(_override(90_000_000, 0.0))              # the operator holds the feed
        k = 10
        while rig.tick(k).feed_override_ratio > 0.0:                    # type: ignore[attr-defined]  # a Reference
            k += 1
            assert k < 200, "the hold never reached the reference"
        rig.overrides.publish(_override(k * 10_000_000, -1.0))         # refused: the hold stays
        held = [rig.tick(k + i) for i in range(1, 6)]
        rig.overrides.publish(_override((k + 5) * 10_000_000, 0.5))    # resume at half speed
        k += 6
        while rig.tick(k).feed_override_ratio < 0.5:                    # type: ignore[attr-defined]  # a Reference
            k += 1
            assert k < 400, "the resume never reached the reference"
    assert all(m.feed_override_ratio == 0.0 and list(m.position_m) == list(held[0].position_m) for m in held)
    ratios = [m.feed_override_ratio for m in rig.references()]
    assert max(abs(a - b) for a, b in zip(ratios, ratios[1:])) < 0.4, "the ratio ramps, it never jumps"
    assert 0.0 in ratios and 0.5 in ratios
    assert rig.references()[-1].position_m != held[0].position_m, "moving again after the hold"


def test_the_interpolator_node_takes_the_previous_ticks_override_exactly(tmp_path: Path) -> None:
    from cnc_contour_control.motion.axis_limits import AxisLimits
    from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig
    from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
    from cnc_contour_control.motion.program_file import read_program_file
    from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
    from cnc_contour_control.testing import InProcessNode, TopicProbe
    from cnc_contour_interfaces.msg import Reference

    with TopicProbe({f"{NS}/reference": Reference}) as probe, \
            InProcessNode(InterpolatorNode, _node_parameters(tmp_path, "previous_tick"), namespace=NS):
        rig = _Rig(probe)
        rig.wait_ready()
        rig.tick(0)                                                      # tick 0 needs no message
        rig.overrides.publish(_override(10_000_000, 1.0))               # tick 1's own message: not enough
        rig.overrides.publish(_override(0, 0.2))                        # tick 0's: tick 1 takes it
        rig.tick(1)
        rig.tick(2)                                                      # takes tick 1's 1.0
    expected = LiveReference(read_program_file(_program_file(tmp_path), ("x", "y")), AxisLimits((0.1, 0.1), (1.0, 1.0)),
                             InterpolatorConfig(), OverrideConfig())
    for k, request in enumerate((1.0, 0.2, 1.0)):
        sample, got = expected.step(k * 10_000_000, request), rig.references()[k]
        assert got.feed_override_ratio == sample.feed_override_ratio
        assert list(got.position_m) == sample.position_m.tolist()
    assert rig.references()[1].feed_override_ratio < 1.0, "tick 1 followed tick 0's 0.2, not the later 1.0"


def test_a_missing_previous_tick_override_is_a_fault_naming_the_topic(tmp_path: Path) -> None:
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
    from cnc_contour_control.testing import InProcessNode, TopicProbe
    from cnc_contour_interfaces.msg import Reference

    parameters = _node_parameters(tmp_path, "previous_tick", feed_override_timeout_s=0.3)
    with TopicProbe({f"{NS}/reference": Reference, "/diagnostics": DiagnosticArray}) as probe, \
            InProcessNode(InterpolatorNode, parameters, namespace=NS) as node:
        rig = _Rig(probe)
        rig.wait_ready()
        rig.tick(0)
        rig.joint_states.publish(_joint_state(10_000_000))              # no feed_override(0) ever comes
        probe.wait_for(lambda: probe.received("/diagnostics"), 10.0, "the interpolator's fault")
        assert node.node.finished
    status = probe.received("/diagnostics")[0].status[0]
    assert status.level == DiagnosticStatus.ERROR
    assert f"no {NS}/feed_override of the previous tick (stamp 0 ns)" in status.message
    assert "feed_override_timeout_s = 0.3 s" in status.message
    assert len(rig.references()) == 1, "tick 1 was never answered without its override"
