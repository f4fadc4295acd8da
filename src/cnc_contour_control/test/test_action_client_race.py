"""Tier 2: an action client whose requests are sent from the test's thread while the probe's executor takes the
answers on its own thread gets every answer (real rclpy, one process, two contexts).

Jazzy's rclpy registers a request's future only after sending the request. The gap between the two is widened
here to 50 ms (a handle that sleeps after each send), so an answer always arrives inside it: rclpy's own client
then drops it ("Ignoring unexpected ... response"); ``ThreadSafeActionClient`` must not.
"""
from __future__ import annotations

import time
import uuid
from typing import Any

import pytest
from rclpy.action import ActionServer
from rclpy.node import Node

from cnc_contour_control.testing import InProcessNode, ThreadSafeActionClient, TopicProbe
from cnc_contour_interfaces.action import RunProgram

pytestmark = pytest.mark.nodes
GAP_S = 0.05


class InstantServer(Node):
    """Accepts every goal and completes it at once, naming the program it was sent."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("instant", **kwargs)
        self.server = ActionServer(self, RunProgram, "run_program", self.execute)

    def execute(self, goal_handle: Any) -> Any:
        goal_handle.succeed()
        return RunProgram.Result(outcome=RunProgram.Result.COMPLETED, program_name=goal_handle.request.program_name)


class SlowSender:
    """The client's C handle, sleeping ``GAP_S`` after every request it sends: an answer arrives in the gap."""

    def __init__(self, handle: Any) -> None:
        self._handle = handle

    def __getattr__(self, name: str) -> Any:
        attribute = getattr(self._handle, name)
        if not name.startswith("send_"):
            return attribute

        def send_then_sleep(request: Any) -> Any:
            sequence = attribute(request)
            time.sleep(GAP_S)
            return sequence

        return send_then_sleep


def test_every_goal_result_and_cancel_is_answered_though_the_answer_beats_the_registration() -> None:
    ns = f"/race_{uuid.uuid4().hex[:8]}"
    with TopicProbe({}) as probe, InProcessNode(InstantServer, {}, namespace=ns):
        client = ThreadSafeActionClient(probe.node, RunProgram, f"{ns}/run_program")
        probe.wait_for(client.server_is_ready, 90.0, "the RunProgram server")
        handle = client._client_handle
        client._client_handle = SlowSender(handle)
        try:
            names = [f"part{i}" for i in range(3)]
            results = []
            for name in names:
                sent = client.send_goal_async(RunProgram.Goal(program_name=name))
                probe.wait_for(sent.done, 90.0, f"the goal response to {name}")
                goal = sent.result()
                cancel = goal.cancel_goal_async()
                probe.wait_for(cancel.done, 90.0, f"the cancel response for {name}")
                result = goal.get_result_async()
                probe.wait_for(result.done, 90.0, f"the result of {name}")
                results.append(result.result().result)
        finally:
            client._client_handle = handle
            client.destroy()
    assert [r.program_name for r in results] == names
    assert all(r.outcome == RunProgram.Result.COMPLETED for r in results)
