"""The ``cnc-contour`` command: a parser per subcommand of :data:`cnc_tools.cli.registry.COMMANDS`.

Exit codes (docs/design.md, "Verdicts"): 0 the command did what it was asked and every verdict it gives is
complete; 1 a run faulted or is partial (a fault during the run, a dead node; a salvaged recording is judged
partial); 2 a usage or input error (a bad option, scenario, program or parameter, a bag that cannot be read at
all: nothing was judged); 128 + N a signal N stopped it (130 for Ctrl-C).
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from cnc_contour_control.core.errors import CncError, FaultError
from cnc_tools.cli.registry import COMMANDS
from cnc_tools.cli.version import VersionAction
from cnc_tools.runs.progress import set_quiet


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The parser of ``cnc-contour``: every registered subcommand listed; configured (its module imported)
    only the one ``argv`` names, or every one when ``argv`` is None."""
    parser = argparse.ArgumentParser(prog="cnc-contour", description="CNC contour-control suite")
    parser.add_argument("--version", action=VersionAction, help="print the suite's version (and git commit) and exit")
    sub = parser.add_subparsers(dest="command", required=True)
    chosen = None if argv is None else next((a for a in argv if not a.startswith("-")), "")
    for name, subcommand in COMMANDS.items():
        sub_parser = sub.add_parser(name, help=subcommand.help, description=subcommand.help)
        sub_parser.add_argument("--quiet", action="store_true", help="no progress on stderr (runs, sweeps, tuning)")
        if chosen is None or name == chosen:
            configure, handler = subcommand.load()
            configure(sub_parser)
            sub_parser.set_defaults(handler=handler)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``cnc-contour``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser(argv).parse_args(argv)
    set_quiet(args.quiet)
    try:
        return int(args.handler(args))
    except CncError as err:
        print(f"cnc-contour {args.command}: error: {err}", file=sys.stderr)
        return exit_code(err)
    except KeyboardInterrupt as err:  # Ctrl-C, or SIGTERM/SIGHUP during a run (RunInterrupted: 128 + signal)
        print(f"cnc-contour {args.command}: {err or 'interrupted'}", file=sys.stderr)
        return int(getattr(err, "exit_code", 130))


#: Exit code of a run that faulted or is partial.
EXIT_FAULTED = 1
#: Exit code of a usage or input error (nothing ran or nothing could be judged).
EXIT_USAGE = 2


def exit_code(err: CncError) -> int:
    """1 for a fault while running (the run faulted), 2 for bad input (a bad option or file: nothing ran)."""
    return EXIT_FAULTED if isinstance(err, FaultError) else EXIT_USAGE


if __name__ == "__main__":
    raise SystemExit(main())
