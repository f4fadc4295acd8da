"""What several subcommands share: ``--set key=value`` overrides and the subcommand record."""
from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import yaml

from cnc_contour_control.errors import CncError

#: A subcommand's handler: parsed arguments in, exit code out.
Handler = Callable[[argparse.Namespace], int]


@dataclass(frozen=True)
class Subcommand:
    """One subcommand: how to configure its parser, what runs it, one line of help."""

    configure: Callable[[argparse.ArgumentParser], None]
    handler: Handler
    help: str


def parse_overrides(items: Sequence[str]) -> dict[str, Any]:
    """``a.b=value`` strings to a nested mapping (values parsed as YAML)."""
    result: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise CncError(f"--set takes key=value, got {item!r}")
        node = result
        *parents, leaf = key.split(".")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = yaml.safe_load(value)
    return result
