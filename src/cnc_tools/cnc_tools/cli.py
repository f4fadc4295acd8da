"""The ``cnc-contour`` command: subcommands from a registry."""
from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import yaml

from cnc_contour_control.errors import CncError

Handler = Callable[[argparse.Namespace], int]
#: name -> (configure parser, handler)
COMMANDS: dict[str, tuple[Callable[[argparse.ArgumentParser], None], Handler]] = {}


def command(name: str, configure: Callable[[argparse.ArgumentParser], None]) -> Callable[[Handler], Handler]:
    """Register a subcommand."""

    def register(handler: Handler) -> Handler:
        COMMANDS[name] = (configure, handler)
        return handler

    return register


def project_root() -> Path:
    """The checkout (CNC_CONTOUR_ROOT, set by ./dev) or the current directory."""
    import os

    return Path(os.environ.get("CNC_CONTOUR_ROOT", Path.cwd()))


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


def timestamp() -> str:
    """A sortable UTC timestamp for run folders."""
    return datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%S_%fZ")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``cnc-contour``."""
    from cnc_tools import commands  # noqa: F401  (registers the subcommands)

    parser = argparse.ArgumentParser(prog="cnc-contour", description="CNC contour-control suite")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (configure, handler) in COMMANDS.items():
        configure_parser = sub.add_parser(name)
        configure(configure_parser)
        configure_parser.set_defaults(handler=handler)
    args = parser.parse_args(argv)
    try:
        return int(args.handler(args))
    except CncError as err:
        print(f"cnc-contour {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"cnc-contour {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    # Run the imported module's main, so subcommands register in the one registry.
    from cnc_tools.cli import main as _imported_main

    raise SystemExit(_imported_main())
