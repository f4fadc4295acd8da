"""Helpers for the tools' node tests: a scenario's graph in this process, on the nodes' own classes.

The runner starts one process per node; a test that drives the graph through its topics, services and actions
(a lifecycle cycle, the ``ros`` command line, programs by action) runs the same nodes, with the parameters the
runner would give them, in process (:class:`cnc_contour_control.testing.InProcessNode`), so it needs no process
start and stops every node when the test ends, also when it fails.
"""
from __future__ import annotations

import os
from collections.abc import Iterator, Mapping
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.nodes.servo_node import ServoNode
from cnc_contour_control.testing import InProcessNode
from cnc_plant_sim.nodes.plant_node import PlantNode
from cnc_tools.runs.dds import claim_free_domain_id
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import Scenario

#: The node class each executable of the core graph spins.
NODE_CLASSES: dict[str, type] = {"plant": PlantNode, "interpolator": InterpolatorNode, "servo": ServoNode}
#: The interpolator serving RunProgram goals (programs by action), feedback and settling quick for a test.
ACTION_MODE: dict[str, Any] = {"program_source": "action", "program_file": "", "settle_time_s": 0.05,
                               "feedback_period_s": 0.05}
#: Per node: a plant that runs until the test ends (no summary file) and the action-mode interpolator.
ACTION_GRAPH: dict[str, dict[str, Any]] = {"plant": {"duration_s": 1.0e5, "summary_file": ""},
                                           "interpolator": ACTION_MODE}


def flat_parameters(mapping: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested parameters as dotted names; empty lists and sections left out (declared defaults)."""
    out: dict[str, Any] = {}
    for key, value in mapping.items():
        if isinstance(value, Mapping):
            out.update(flat_parameters(value, f"{prefix}{key}."))
        elif not (isinstance(value, (list, tuple)) and not value):
            out[f"{prefix}{key}"] = value
    return out


def start_graph_in_process(stack: ExitStack, scenario: Scenario, run_dir: Path,
                           overrides: Mapping[str, Mapping[str, Any]] = ACTION_GRAPH) -> dict[str, Any]:
    """Start ``scenario``'s core graph in this process (each node's parameters as the runner writes them, then
    ``overrides`` by node name), stopped when ``stack`` closes; the nodes by name."""
    nodes = {}
    for spec in graph_specs(scenario, run_dir, extra_subscribers=0):
        params = {**flat_parameters(dict(spec.parameters)), **overrides.get(spec.name, {})}

        def factory(node_class: type = NODE_CLASSES[spec.executable], name: str = spec.name, **kwargs: Any) -> Any:
            return node_class(cli_args=["--ros-args", "-r", f"__node:={name}"], **kwargs)

        nodes[spec.name] = stack.enter_context(InProcessNode(factory, params)).node
    return nodes


@contextmanager
def own_domain() -> Iterator[int]:
    """While the block runs, ``ROS_DOMAIN_ID`` is a domain claimed for it alone (no other process on this host
    holds it; released after): for a test module that hosts a ``/cnc`` graph in its worker process. After another
    in-process graph of the same worker, in the worker's own domain, such a graph's services and goals went
    unanswered for 60-90 s (a RunProgram goal, get_state; also at f4b6fda); what the earlier graph leaves there
    is not found yet."""
    claim = claim_free_domain_id()
    before = os.environ.get("ROS_DOMAIN_ID")
    os.environ["ROS_DOMAIN_ID"] = str(claim.domain_id)
    try:
        yield claim.domain_id
    finally:
        if before is None:
            os.environ.pop("ROS_DOMAIN_ID", None)
        else:
            os.environ["ROS_DOMAIN_ID"] = before
        claim.release()
