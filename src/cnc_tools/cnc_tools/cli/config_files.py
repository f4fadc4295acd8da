"""``cnc-contour config-files [--check]``: write (or check) the parameter files the packages install.

The files (``src/<package>/config/<scenario>.params.yaml`` and its program,
:data:`cnc_tools.runs.installed_params.INSTALLED`) are generated from their
scenarios by the runner's code; ``./dev setup`` installs them under
``share/<package>/config/``, where the launch file and ``--params-file`` by
hand find them. Run it after a change to a node's parameters or a scenario.
"""
from __future__ import annotations

import argparse

from cnc_tools.runs.installed_params import stale_files, write_installed


def configure(parser: argparse.ArgumentParser) -> None:
    """Options of ``cnc-contour config-files``."""
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 if a committed file differs from what the code generates")


def config_files(args: argparse.Namespace) -> int:
    """Write the installed parameter files, or check them."""
    if args.check:
        stale = stale_files()
        for path in stale:
            print(f"stale: {path} (regenerate: cnc-contour config-files)")
        return 1 if stale else 0
    for path in write_installed():
        print(path)
    return 0
