"""What several subcommands share: ``--set key=value`` overrides and the subcommand record."""
from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import yaml

from cnc_contour_control.core.config import load_yaml
from cnc_contour_control.core.errors import CncError

#: A subcommand's handler: parsed arguments in, exit code out.
Handler = Callable[[argparse.Namespace], int]


@dataclass(frozen=True)
class Subcommand:
    """One subcommand: its module, the names of the function that configures its parser and of the one that
    runs it, and one line of help. The module is imported only when the subcommand is used (``load``): a
    ``cnc-contour`` call imports what its own subcommand needs, not every bench and plot of the suite."""

    module: str
    configure_name: str
    handler_name: str
    help: str

    def load(self) -> tuple[Callable[[argparse.ArgumentParser], None], Handler]:
        """The subcommand's configure function and handler (its module imported now)."""
        module = importlib.import_module(self.module)
        return getattr(module, self.configure_name), getattr(module, self.handler_name)


def parse_overrides(items: Sequence[str]) -> dict[str, Any]:
    """``a.b=value`` strings to a nested mapping (values parsed as YAML, floats as YAML 1.2 writes them: ``8e-4``)."""
    result: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise CncError(f"--set takes key=value, got {item!r}")
        node = result
        *parents, leaf = key.split(".")
        for part in parents:
            node = node.setdefault(part, {})
        try:
            node[leaf] = load_yaml(value)
        except yaml.YAMLError as err:
            raise CncError(f"--set {key}: {value!r} is not a YAML value ({' '.join(str(err).split())})") from err
    return result
