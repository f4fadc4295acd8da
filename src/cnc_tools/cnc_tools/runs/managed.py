"""A managed graph: the lifecycle nodes wait unconfigured and a lifecycle manager drives them (``run --managed``).

The interpolator, the servos and the plant are lifecycle nodes
(:mod:`cnc_contour_control.nodes.lifecycle`). By default they configure and
activate themselves when started (an autostart); managed, each gets
``managed: true`` and the run gets a ``lifecycle_manager`` node that
configures every one of them, then activates them, the plant last (it starts
the clock). The other nodes (estimator, compensator, force regulator,
recorder) are plain nodes and start as before.
"""
from __future__ import annotations

from collections.abc import Sequence

from cnc_tools.runs.graph_nodes import NodeSpec

#: The executables whose nodes are lifecycle nodes, in the order the manager brings them up (the plant last).
MANAGED_ORDER = (("cnc_contour_control", "interpolator"), ("cnc_contour_control", "servo"), ("cnc_plant_sim", "plant"))
MANAGER = NodeSpec("cnc_tools", "lifecycle_manager", "lifecycle_manager", {})


def managed_nodes(nodes: Sequence[NodeSpec]) -> list[NodeSpec]:
    """``nodes`` with the lifecycle nodes set to wait for the manager, and the manager that drives them."""
    rank = {key: k for k, key in enumerate(MANAGED_ORDER)}
    managed = sorted((spec for spec in nodes if (spec.package, spec.executable) in rank),
                     key=lambda spec: rank[(spec.package, spec.executable)])
    names = {spec.name for spec in managed}
    out = [NodeSpec(s.package, s.executable, s.name, {**s.parameters, "managed": True}) if s.name in names else s
           for s in nodes]
    manager = NodeSpec(MANAGER.package, MANAGER.executable, MANAGER.name, {"node_names": [s.name for s in managed]})
    return [*out, manager]
