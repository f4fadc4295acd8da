"""Tier 2: the recorder reads joint_states (the plant's start gate) only once it can hear the plant's run end."""
from __future__ import annotations

from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import JointState

from cnc_contour_control.nodes.common import LATCHED_QOS
from cnc_contour_control.testing import InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import Path as PathMsg
from cnc_contour_interfaces.msg import Reference
from cnc_tools.nodes.recorder_node import RecorderNode
from cnc_tools.runs.namespaces import run_namespace

pytestmark = pytest.mark.nodes


def test_joint_states_is_read_only_after_the_plants_diagnostics_writer_is_known(tmp_path: Path) -> None:
    params = {"output": str(tmp_path / "bag"), "latched_first": True}
    ns = run_namespace()  # a node of an earlier test killed in /cnc stays in the graph until its lease ends (~20 s)
    with TopicProbe({"/diagnostics": DiagnosticArray}, name="plant", namespace=ns) as plant:
        path = plant.node.create_publisher(PathMsg, f"{ns}/path", LATCHED_QOS)
        path.publish(PathMsg())
        joint_states = plant.publisher(JointState, f"{ns}/joint_states")
        reference = plant.publisher(Reference, f"{ns}/reference")
        with InProcessNode(RecorderNode, params, namespace=ns):
            plant.wait_for(lambda: reference.get_subscription_count() == 1, 20.0, "the recorder's reference reader")
            # the recorder reads the other per-tick topics; joint_states waits, and says why (STALE, after 1 s)
            plant.wait_for(lambda: any(f"a /diagnostics writer of {ns}/plant (publisher of {ns}/joint_states)"
                                       in status.message for array in plant.received("/diagnostics")
                                       for status in array.status), 20.0, "the recorder's wait on /diagnostics")
            assert joint_states.get_subscription_count() == 0, "joint_states read before the plant can be heard"
            plant.node.create_publisher(DiagnosticArray, "/diagnostics", 100)
            plant.wait_for(lambda: joint_states.get_subscription_count() == 1, 20.0,
                           "the recorder's joint_states reader once /diagnostics has a writer of the plant")


def test_a_plant_that_leaves_before_its_run_end_is_heard_is_a_fault_and_the_bag_keeps_what_came(tmp_path: Path) -> None:
    """No recorder waits for ever on a run end that will not come (a plant killed, a report lost)."""
    params = {"output": str(tmp_path / "bag"), "drain_timeout_s": 0.5}
    ns = run_namespace()  # a node of an earlier test killed in /cnc stays in the graph until its lease ends (~20 s)
    with TopicProbe({}, name="plant", namespace=ns) as plant:
        joint_states = plant.publisher(JointState, f"{ns}/joint_states")
        with InProcessNode(RecorderNode, params, namespace=ns) as recorder:
            plant.wait_for(lambda: joint_states.get_subscription_count() == 1, 20.0,
                           "the recorder's joint_states reader")
            for tick in range(3):
                message = JointState()
                message.header.stamp.nanosec = 1_000_000 * (tick + 1)
                joint_states.publish(message)
            plant.wait_for(lambda: recorder.node.writer.message_counts.get(f"{ns}/joint_states") == 3, 20.0,
                           "three joint_states in the bag")
            assert recorder.node.fault_message is None, "the plant is still there: the recorder waits"
            plant.node.destroy_publisher(joint_states)
            plant.wait_for(lambda: recorder.node.fault_message is not None, 20.0, "the recorder's fault")
    message = recorder.node.fault_message
    assert f"the publisher of {ns}/joint_states left the graph" in message and "run finished" in message, message
    assert "within 0.5 s" in message and f"3 {ns}/joint_states messages" in message, message
    with AnyReader([tmp_path / "bag"]) as reader:
        assert sum(1 for c in reader.connections if c.topic == f"{ns}/joint_states"
                   for _ in reader.messages(connections=[c])) == 3
