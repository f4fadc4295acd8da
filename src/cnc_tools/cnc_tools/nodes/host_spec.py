"""The files between the runner and a composed host: the host's spec and its members' exits.

The runner writes ``<process>.compose.yaml`` (the members and each one's ROS
arguments, :func:`cnc_tools.runs.compose.write_host_spec`); the host
(:mod:`cnc_tools.nodes.composed_host`) reads it and notes each member that
ends in ``<process>.exits.json``, which the runner polls.
"""
from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from cnc_contour_control.core.errors import ConfigError

#: Name of the composed process (its log, spec and exits files are named after it).
HOST = "composed"


def spec_path(run_dir: Path, process: str) -> Path:
    """The host's spec file in the run folder."""
    return run_dir / f"{process}.compose.yaml"


def exits_path(run_dir: Path, process: str) -> Path:
    """The file where the host notes its members' ends."""
    return run_dir / f"{process}.exits.json"


@dataclass(frozen=True)
class MemberExit:
    """How a member of a composed process ended: its exit code, as its own process would have, and last line."""

    code: int
    message: str


def read_exits(path: Path) -> dict[str, MemberExit]:
    """The members that ended so far (none while the file is absent)."""
    try:
        raw = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return {name: MemberExit(int(entry["code"]), str(entry["message"])) for name, entry in raw.items()}


def write_exits(path: Path, exits: Mapping[str, MemberExit]) -> None:
    """Write the members' ends atomically (the runner polls the file)."""
    partial = path.with_name(f".{path.name}.partial")
    partial.write_text(json.dumps({name: {"code": e.code, "message": e.message} for name, e in exits.items()}))
    os.replace(partial, path)


def read_host_spec(path: Path) -> dict[str, Any]:
    """A host spec as written by :func:`write_host_spec`."""
    spec = yaml.safe_load(path.read_text())
    if not isinstance(spec, dict) or not isinstance(spec.get("nodes"), list) or not spec["nodes"]:
        raise ConfigError(f"composed host spec {path} must hold a non-empty list 'nodes', got {spec!r}")
    return spec
