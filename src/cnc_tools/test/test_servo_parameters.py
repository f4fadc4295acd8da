"""Tier 2: the servo's parameters with real nodes: gains set at run time, and ``-p axis:=y`` on a real process."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Any

import pytest
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.nodes.common import ns_to_stamp
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_contour_control.testing import WAIT_FLOOR_S, InProcessNode, TopicProbe
from cnc_contour_interfaces.msg import AxisCommand, Reference
from cnc_tools.runs.dds import loopback_env
from cnc_tools.runs.graph import find_executable
from cnc_tools.runs.lifetime import stop_process

pytestmark = pytest.mark.nodes
GAINS = {"kp": 2.4, "ki": 10.0, "kd": 0.067}
PARAMS = {"axis": "x", "sample_time_s": 0.01, "law": "pid", "input_timeout_s": 30.0,
          **{f"gains.{k}": v for k, v in GAINS.items()}}
COMMAND = "/cnc/servo/x/command"


def _header(stamp_ns: int) -> Header:
    return Header(stamp=ns_to_stamp(stamp_ns), frame_id="machine")


def _tick(pubs: dict[str, Any], k: int) -> tuple[float, float]:
    """Publish tick ``k``'s reference and joint state; (reference, position) of x [m]."""
    x_ref, x = 2e-6 * k * k, 1e-6 * k * k  # errors of 0.1 k^2 BLU: no saturation
    pubs["reference"].publish(Reference(header=_header(k * 10_000_000), axis_names=["x", "y"], position_m=[x_ref, 0.0],
                                        velocity_m_s=[1e-3, 0.0], acceleration_m_s2=[0.0, 0.0]))
    pubs["joint_states"].publish(JointState(header=_header(k * 10_000_000), name=["x", "y"], position=[x, 0.0],
                                            velocity=[0.0, 0.0]))
    return x_ref, x


def _set(probe: TopicProbe, client: AsyncParameterClient, parameter: Parameter) -> Any:
    """Set one parameter through the node's parameter service (as ``ros2 param set`` does)."""
    future = client.set_parameters([parameter])
    probe.wait_for(future.done, 10.0, f"the answer to setting {parameter.name}")
    return future.result().results[0]


def test_a_gain_set_at_run_time_is_applied_keeping_the_laws_state_and_a_bad_one_refused() -> None:
    before = ServoConfig.from_mapping({"axis_name": "x", "law": "pid", "law_params": GAINS})
    after = ServoConfig.from_mapping({"axis_name": "x", "law": "pid", "law_params": {**GAINS, "ki": 30.0}})
    retuned, fresh = ServoController(before), ServoController(after)
    with TopicProbe({COMMAND: AxisCommand}) as probe, InProcessNode(ServoNode, PARAMS) as servo:
        pubs = {t: probe.publisher(m, f"/cnc/{t}") for t, m in (("joint_states", JointState), ("reference", Reference))}
        probe.wait_for(lambda: all(p.get_subscription_count() for p in pubs.values()), 10.0, "the servo's inputs")
        client = AsyncParameterClient(probe.node, "/cnc/servo")
        assert client.wait_for_services(WAIT_FLOOR_S)
        expected, restarted = [], []
        for k in range(12):
            if k == 6:
                refused = _set(probe, client, Parameter("gains.kp", value=-1.0))
                assert not refused.successful and "gains.kp" in refused.reason and "-1.0" in refused.reason
                assert _set(probe, client, Parameter("gains.ki", value=30.0)).successful
                retuned.retune(after)
            x_ref, x = _tick(pubs, k)
            expected.append(retuned.step(0.01, x_ref, 1e-3, 0.0, x, 0.0, 0.0).command)
            if k >= 6:
                restarted.append(fresh.step(0.01, x_ref, 1e-3, 0.0, x, 0.0, 0.0).command)
            probe.wait_for(lambda k=k: len(probe.received(COMMAND)) == k + 1, 10.0, f"command {k}")
        assert servo.node.controller.law.config == after.law_config()
    commands = [m.command for m in probe.received(COMMAND)]
    assert commands == expected, "the change applied from tick 6, the law's state (its integral) kept"
    assert commands[6:] != restarted and max(map(abs, commands)) < 127.0, \
        "a law restarted at the change would command otherwise (so the check can fail)"


@pytest.mark.parametrize("axis", ["y", "on"])
def test_a_servo_process_started_with_p_axis_y_drives_axis_y(tmp_path: Path, axis: str) -> None:
    namespace = f"/axis_{axis}_{os.getpid()}"  # its own topics, whatever else runs in this domain
    command = [str(find_executable("cnc_contour_control", "servo")), "--ros-args", "-r", f"__ns:={namespace}",
               "-p", f"axis:={axis}"]  # rcl's YAML 1.1 reads an unquoted y or on as the boolean true
    with open(tmp_path / "servo.log", "wb") as log:
        process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=loopback_env(),
                                   start_new_session=True)
    try:
        with TopicProbe({}, name="axis_probe") as probe:
            probe.wait_for(lambda: process.poll() is not None
                           or probe.node.count_publishers(f"{namespace}/servo/{axis}/command") > 0, 60.0, "the servo")
            assert process.poll() is None, (tmp_path / "servo.log").read_text()
            client = AsyncParameterClient(probe.node, f"{namespace}/servo")
            assert client.wait_for_services(WAIT_FLOOR_S)
            future = client.get_parameters(["axis"])
            probe.wait_for(future.done, 10.0, "the axis parameter")
        value = future.result().values[0]
        assert (value.type, value.string_value) == (ParameterType.PARAMETER_STRING, axis)
    finally:
        stop_process(process, 15.0)
    assert process.returncode == 0, (tmp_path / "servo.log").read_text()


