"""Which nodes of a run share one process (``--compose all|loop|none``), and the files between runner and host.

A composed process hosts several of the suite's node classes on one executor
(the ROS 2 component pattern, :mod:`cnc_tools.nodes.composed_host`): the same
classes, names, namespace, parameters files and remaps as separate processes,
so the topics, the bag and the verdicts are the same. The modes:

* ``none``: one process per node (what the runner always did);
* ``loop``: the nodes of the per-tick loop (every stage of the pipeline,
  :data:`cnc_contour_control.core.stages.PIPELINE`: plant, interpolator, servos,
  estimator, compensator, force regulator) in one process; the recorder apart;
* ``all``: every node of the run in one process, the recorder included.

Runner and host talk through two files in the run folder: the host's spec
``<process>.compose.yaml`` (its nodes and each node's ROS arguments) and
``<process>.exits.json``, where the host notes each member that ended (exit
code and last line, as if it had been a process of its own), so the runner
supervises members as it supervises processes.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import yaml

from cnc_contour_control.core.config import require_choice
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.stages import PIPELINE
from cnc_tools.nodes.composable import check_composable
from cnc_tools.nodes.host_spec import HOST, exits_path, spec_path
from cnc_tools.runs.graph_nodes import NodeSpec

#: The loop's node kinds: every stage of the pipeline.
LOOP_EXECUTABLES = frozenset((stage.package, stage.executable) for stage in PIPELINE)


def _in_loop(spec: NodeSpec) -> bool:
    return (spec.package, spec.executable) in LOOP_EXECUTABLES


#: Compose mode -> which nodes join the composed process.
COMPOSE_MODES: dict[str, Callable[[NodeSpec], bool]] = {
    "none": lambda spec: False,
    "loop": _in_loop,
    "all": lambda spec: True,
}


@dataclass(frozen=True)
class ProcessGroup:
    """One process of a run: its name and the nodes it runs (one, or several when composed)."""

    name: str
    nodes: tuple[NodeSpec, ...]


def group_nodes(nodes: Sequence[NodeSpec], mode: str) -> list[ProcessGroup]:
    """The processes of a run: the composed host first (if any node joins it), then one per remaining node."""
    joins = COMPOSE_MODES[require_choice("compose", mode, COMPOSE_MODES)]
    members = tuple(spec for spec in nodes if joins(spec))
    for spec in members:
        check_composable(spec.package, spec.executable)
    alone = [ProcessGroup(spec.name, (spec,)) for spec in nodes if not joins(spec)]
    if any(group.name == HOST for group in alone):
        raise ConfigError(f"node name {HOST!r} is the composed process's; name the node otherwise")
    return [ProcessGroup(HOST, members), *alone] if members else alone


def write_host_spec(run_dir: Path, group: ProcessGroup, arguments: Mapping[str, Sequence[str]]) -> Path:
    """Write ``<process>.compose.yaml``: each member's package, executable, name and ROS arguments."""
    nodes = [{"package": spec.package, "executable": spec.executable, "name": spec.name,
              "arguments": list(arguments[spec.name])} for spec in group.nodes]
    path = spec_path(run_dir, group.name)
    path.write_text(yaml.safe_dump({"process": group.name, "exits_file": str(exits_path(run_dir, group.name)),
                                    "nodes": nodes}, sort_keys=False))
    return path
