"""A whole graph in one ROS 2 parameters file (ROS-free): one section per node, ``/**`` for what they share.

::

    /**:                         every parameter that more than one node has, each with the same value
      ros__parameters: {sample_time_s: 0.01, gains: {kp: 2.4, ...}, ...}
    /cnc/plant:
      ros__parameters: {model: "paper000", ...}
    /cnc/interpolator: ...
    /cnc/servo_x: ...

The sections are the nodes' parameters as the runner writes them
(:func:`cnc_contour_control.graph.graph_files.params_yaml`: the same quoting dumper),
so rcl gives each node what the runner's own file would give it; a value
shared by several nodes (the sample time, the servos' gains) is written once.
The nodes to start are the file's sections: a section ``<namespace>/<name>``
is the node of the stage named ``name`` (``servo_<axis>`` for a per-axis
stage), and the stage names its package and executable
(:data:`cnc_contour_control.core.stages.STAGES`), or the suite's recorder
(:data:`TOOL_NODES`), so the file is the whole graph.

A relative path in the file (the program) is relative to the file's folder:
the launch file starts every node there, and by hand one starts them there.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from cnc_contour_control.core.config import read_yaml_mapping
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.stages import STAGES, Stage
from cnc_contour_control.graph.graph_files import GraphNode, _QuotedDumper

#: The section of the parameters every node that has them shares (rcl's wildcard for any node).
SHARED_SECTION = "/**"
#: Nodes of a graph that are no stage: name -> (package, executable) (the suite's recorder).
TOOL_NODES: dict[str, tuple[str, str]] = {"recorder": ("cnc_tools", "recorder")}
_PARAMETERS = "ros__parameters"


def flatten(mapping: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested parameters as dotted names (``{"gains": {"kp": 2}}`` -> ``{"gains.kp": 2}``); lists stay values."""
    out: dict[str, Any] = {}
    for key, value in mapping.items():
        if isinstance(value, Mapping):
            out.update(flatten(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = list(value) if isinstance(value, tuple) else value
    return out


def nest(flat: Mapping[str, Any]) -> dict[str, Any]:
    """Dotted names back to nested mappings, in the given order (the inverse of :func:`flatten`)."""
    out: dict[str, Any] = {}
    for name, value in flat.items():
        *sections, last = name.split(".")
        target = out
        for section in sections:
            target = target.setdefault(section, {})
        target[last] = value
    return out


def shared_parameters(nodes: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The dotted parameters that at least two of ``nodes`` (flat) have, each node with the same value."""
    seen: dict[str, list[Any]] = {}
    for flat in nodes:
        for name, value in flat.items():
            seen.setdefault(name, []).append(value)
    return {name: values[0] for name, values in seen.items()
            if len(values) > 1 and all(_same(v, values[0]) for v in values)}


def _same(a: Any, b: Any) -> bool:
    """Equal and of one type (``1`` and ``1.0``, ``True`` and ``1`` are different parameters to rcl)."""
    return type(a) is type(b) and a == b


def graph_params_yaml(namespace: str, nodes: Sequence[tuple[str, Mapping[str, Any]]]) -> str:
    """One parameters file for the nodes ``(name, parameters)`` in ``namespace``; shared values under ``/**``.

    Empty mappings are left out, as in :func:`~cnc_contour_control.graph.graph_files.params_yaml`
    (rcl refuses an empty one).
    """
    if not nodes:
        raise ConfigError("a graph parameters file needs at least one node, got none")
    flats = [flatten(parameters) for _, parameters in nodes]
    shared = shared_parameters(flats)
    document: dict[str, Any] = {SHARED_SECTION: {_PARAMETERS: nest(shared)}} if shared else {}
    prefix = namespace.rstrip("/")
    for (name, _), flat in zip(nodes, flats):
        own = {key: value for key, value in flat.items() if key not in shared}
        document[f"{prefix}/{name}"] = {_PARAMETERS: nest(own)}
    return yaml.dump(document, Dumper=_QuotedDumper, sort_keys=False)


def stage_of(node_name: str) -> Stage:
    """The stage whose node ``node_name`` is (``servo_x`` -> the servo stage); a ConfigError listing them."""
    stage = STAGES.get(node_name)
    if stage is not None and not stage.per_axis:
        return stage
    for candidate in STAGES.values():
        axis = node_name.removeprefix(f"{candidate.name}_")
        if candidate.per_axis and axis and axis != node_name:
            return candidate
    names = sorted([*(f"{s.name}_<axis>" if s.per_axis else s.name for s in STAGES.values()), *TOOL_NODES])
    raise ConfigError(f"node {node_name!r} is no stage's node; node names: {names}")


def read_graph_params(path: str | Path) -> list[GraphNode]:
    """The nodes of the graph parameters file ``path``, in its order (a ConfigError naming what is wrong)."""
    file = Path(path)
    document = read_yaml_mapping(file, "graph parameters file")
    nodes = [_graph_node(file, key, section) for key, section in document.items() if key != SHARED_SECTION]
    if not nodes:
        raise ConfigError(f"graph parameters file {str(file)!r} names no node (sections such as /cnc/plant)")
    return nodes


def _graph_node(file: Path, key: Any, section: Any) -> GraphNode:
    if not isinstance(key, str) or not key.startswith("/") or not isinstance(section, Mapping) \
            or _PARAMETERS not in section:
        raise ConfigError(f"graph parameters file {str(file)!r}: section {key!r} must be a fully qualified "
                          f"node name (/cnc/plant) holding {_PARAMETERS}")
    namespace, name = key.rsplit("/", 1)
    package, executable = node_executable(name)
    return GraphNode(name, package, executable, namespace or "/", file.resolve())


def node_executable(node_name: str) -> tuple[str, str]:
    """(package, executable) of the node ``node_name``: a stage's node or one of :data:`TOOL_NODES`."""
    if node_name in TOOL_NODES:
        return TOOL_NODES[node_name]
    stage = stage_of(node_name)
    return stage.package, stage.executable
