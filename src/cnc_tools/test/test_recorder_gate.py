"""Tier 2: the recorder reads joint_states (the plant's start gate) only once it can hear the plant's run end."""
from __future__ import annotations

from pathlib import Path

import pytest
from cnc_contour_interfaces.msg import Path as PathMsg
from cnc_contour_interfaces.msg import Reference
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState

from cnc_contour_control.nodes.common import LATCHED_QOS
from cnc_tools.nodes.recorder_node import RecorderNode
from cnc_tools.testing import InProcessNode, TopicProbe

pytestmark = pytest.mark.nodes


def test_joint_states_is_read_only_after_the_plants_diagnostics_writer_is_known(tmp_path: Path) -> None:
    params = {"output": str(tmp_path / "bag"), "latched_first": True}
    with TopicProbe({"/diagnostics": DiagnosticArray}, name="plant", namespace="/cnc") as plant:
        path = plant.node.create_publisher(PathMsg, "/cnc/path", LATCHED_QOS)
        path.publish(PathMsg())
        joint_states = plant.publisher(JointState, "/cnc/joint_states")
        reference = plant.publisher(Reference, "/cnc/reference")
        with InProcessNode(RecorderNode, params):
            plant.wait_for(lambda: reference.get_subscription_count() == 1, 20.0, "the recorder's reference reader")
            # the recorder reads the other per-tick topics; joint_states waits, and says why (STALE, after 1 s)
            plant.wait_for(lambda: any("a /diagnostics writer of /cnc/plant (publisher of /cnc/joint_states)"
                                       in status.message for array in plant.received("/diagnostics")
                                       for status in array.status), 20.0, "the recorder's wait on /diagnostics")
            assert joint_states.get_subscription_count() == 0, "joint_states read before the plant can be heard"
            plant.node.create_publisher(DiagnosticArray, "/diagnostics", 100)
            plant.wait_for(lambda: joint_states.get_subscription_count() == 1, 20.0,
                           "the recorder's joint_states reader once /diagnostics has a writer of the plant")
