"""A graph's parameter folder: one ROS 2 parameters file per node and the list of nodes (ROS-free).

The runner writes it into every run folder (and ``cnc-contour params`` into any
folder); the launch file ``contour_graph.launch.py`` starts the nodes it lists
with these files, so a launched graph and a run of the same scenario get the
same parameters::

    graph.yaml              namespace: /cnc
                            nodes: [{name: plant, package: cnc_plant_sim, executable: plant,
                                     parameters_file: plant.params.yaml}, ...]
    plant.params.yaml       /cnc/plant: {ros__parameters: {...}}
    servo_x.params.yaml     ...

Every string in a parameters file is written quoted: rcl's YAML 1.1 parser
reads an unquoted ``y``, ``n``, ``yes``, ``no``, ``on`` or ``off`` as a
boolean (axis ``y`` would become ``true``).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from cnc_contour_control.core.config import read_yaml_mapping
from cnc_contour_control.core.errors import ConfigError

#: The node list of a parameter folder.
MANIFEST = "graph.yaml"
_NODE_KEYS = ("name", "package", "executable", "parameters_file")


@dataclass(frozen=True)
class GraphNode:
    """One node of a parameter folder (``parameters_file`` absolute once read)."""

    name: str
    package: str
    executable: str
    namespace: str
    parameters_file: Path

    @property
    def full_name(self) -> str:
        """The node's fully qualified name (``/cnc/servo_x``), the key of its parameters file."""
        return f"{self.namespace.rstrip('/')}/{self.name}"


class _QuotedDumper(yaml.SafeDumper):  # type: ignore[misc]  # PyYAML ships no types (SafeDumper is Any)
    """Quotes every string, so rcl's YAML 1.1 parser never reads 'y' or 'no' as a bool."""


_QuotedDumper.add_representer(
    str, lambda dumper, value: dumper.represent_scalar("tag:yaml.org,2002:str", value, style='"'))


def params_yaml(full_name: str, parameters: Mapping[str, Any]) -> str:
    """A ROS 2 parameters file for the node ``full_name`` (nested mappings are dotted parameter names).

    An empty mapping holds no parameter and is left out (rcl refuses an empty one).
    """
    body = _without_empty(parameters)
    return yaml.dump({full_name: {"ros__parameters": body}}, Dumper=_QuotedDumper, sort_keys=False)


def _without_empty(mapping: Mapping[str, Any]) -> dict[str, Any]:
    out = {}
    for key, value in mapping.items():
        if isinstance(value, Mapping):
            value = _without_empty(value)
            if not value:
                continue
        out[key] = value
    return out


def params_file_name(node_name: str) -> str:
    """The file name of a node's parameters in a folder."""
    return f"{node_name}.params.yaml"


def write_params_file(folder: Path, namespace: str, name: str, parameters: Mapping[str, Any]) -> Path:
    """Write one node's parameters file into ``folder``; its path."""
    path = folder / params_file_name(name)
    path.write_text(params_yaml(f"{namespace.rstrip('/')}/{name}", parameters))
    return path


def write_manifest(folder: Path, namespace: str, nodes: Sequence[tuple[str, str, str]]) -> Path:
    """Write ``graph.yaml`` listing ``(package, executable, name)`` of each node (files by :func:`params_file_name`)."""
    entries = [{"name": name, "package": package, "executable": executable,
                "parameters_file": params_file_name(name)} for package, executable, name in nodes]
    path = folder / MANIFEST
    path.write_text(yaml.dump({"namespace": namespace, "nodes": entries}, Dumper=_QuotedDumper, sort_keys=False))
    return path


def read_manifest(folder: str | Path) -> list[GraphNode]:
    """The nodes of the parameter folder ``folder`` (a ConfigError naming what is missing or wrong)."""
    root = Path(folder)
    document = read_yaml_mapping(root / MANIFEST, "graph manifest")
    namespace, entries = document.get("namespace", "/"), document.get("nodes")
    if not isinstance(namespace, str) or not isinstance(entries, list) or not entries:
        raise ConfigError(f"{root / MANIFEST}: needs a namespace and a non-empty list of nodes")
    return [_node(root, namespace, i, entry) for i, entry in enumerate(entries)]


def _node(root: Path, namespace: str, index: int, entry: Any) -> GraphNode:
    if not isinstance(entry, Mapping) or any(not isinstance(entry.get(k), str) for k in _NODE_KEYS):
        raise ConfigError(f"{root / MANIFEST}: nodes[{index}] must give {list(_NODE_KEYS)} as strings, got {entry!r}")
    path = root / entry["parameters_file"]
    if not path.is_file():
        raise ConfigError(f"{root / MANIFEST}: nodes[{index}].parameters_file {str(path)!r} does not exist")
    return GraphNode(entry["name"], entry["package"], entry["executable"], namespace, path.resolve())
