"""The ``cnc-contour`` command: a parser per subcommand of :data:`cnc_tools.cli.registry.COMMANDS`."""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from cnc_contour_control.errors import CncError
from cnc_tools.cli.registry import COMMANDS


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``cnc-contour`` with every registered subcommand."""
    parser = argparse.ArgumentParser(prog="cnc-contour", description="CNC contour-control suite")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, subcommand in COMMANDS.items():
        sub_parser = sub.add_parser(name, help=subcommand.help, description=subcommand.help)
        subcommand.configure(sub_parser)
        sub_parser.set_defaults(handler=subcommand.handler)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``cnc-contour``."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.handler(args))
    except CncError as err:
        print(f"cnc-contour {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as err:  # Ctrl-C, or SIGTERM/SIGHUP during a run (RunInterrupted: 128 + signal)
        print(f"cnc-contour {args.command}: {err or 'interrupted'}", file=sys.stderr)
        return int(getattr(err, "exit_code", 130))


if __name__ == "__main__":
    raise SystemExit(main())
