"""``python -m cnc_tools.bench.paper000_cli NAME [--quick] [--engine] [--seeds N] [--json PATH] [--out DIR]``.

The paper-000 benches with all their options, for as long as the ``bench``
subcommand does not offer ``--engine`` and ``--seeds`` (it passes ``--quick``,
``--json`` and ``--out``; the benches then use their default seeds and the
node graph).
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from cnc_contour_control.errors import CncError
from cnc_tools.bench import get_bench

#: The benches this entry point runs.
NAMES = ("paper000", "paper000-pid", "paper000-assumptions")


def parser() -> argparse.ArgumentParser:
    """The options of the paper-000 benches."""
    p = argparse.ArgumentParser(prog="python -m cnc_tools.bench.paper000_cli",
                                description="Paper 000 reproduction benches (docs/reproduction.md)")
    p.add_argument("name", choices=NAMES)
    p.add_argument("--quick", action="store_true", help="line_low only, one seed")
    p.add_argument("--engine", action="store_true", help="every run in-process (no node graph)")
    p.add_argument("--seeds", type=int, help="plant seeds 1..N per row")
    p.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    p.add_argument("--out", type=Path, help="folder for run files and figures")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the options and run the bench; a configuration error is reported, exit code 2."""
    args = parser().parse_args(argv)
    try:
        return get_bench(args.name)(args)
    except CncError as err:
        print(f"paper000 bench {args.name}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
