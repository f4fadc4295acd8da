"""Benchmarks of ``cnc-contour bench NAME``: figures measured side by side in one run.

A bench is a function ``(options) -> exit code`` registered by name with
:func:`register_bench`. It measures, prints a table, returns 0 once every
measurement ran (a goal that is not met is reported, not an error), and
writes its figures as JSON to ``options.json`` when that is set. The options
are those of the ``bench`` subcommand (:mod:`cnc_tools.bench.command`):
``name``, ``quick`` (a shorter run), ``json`` and ``out`` (a folder for run
files, or None).

Adding a bench: a module in this package that decorates its function with
``@register_bench("name")``, imported at the bottom of this file.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable

from cnc_contour_control.config import require_choice

#: A bench: parsed options in, exit code out.
Bench = Callable[[argparse.Namespace], int]
#: Benches by name.
BENCHES: dict[str, Bench] = {}


def register_bench(name: str) -> Callable[[Bench], Bench]:
    """Register a bench function under ``name``."""

    def register(function: Bench) -> Bench:
        BENCHES[name] = function
        return function

    return register


def get_bench(name: str) -> Bench:
    """The bench called ``name``; an unknown name is a ConfigError listing the valid ones."""
    require_choice("bench", name, BENCHES)
    return BENCHES[name]


from cnc_tools.bench import lockstep as _lockstep  # noqa: E402,F401  (registers "lockstep")
from cnc_tools.bench import scoring as _scoring  # noqa: E402,F401  (registers "scoring")
from cnc_tools.bench import paper000 as _paper000  # noqa: E402,F401  (registers "paper000", "paper000-pid", "paper000-assumptions")
from cnc_tools.bench import laws as _laws  # noqa: E402,F401  (registers "laws")
