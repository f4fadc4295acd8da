"""Bench ``fuzz``: seeded random inputs of four kinds, each run with a time bound (issue 22, item 6).

``cnc-contour bench fuzz [--count N] [--kinds gcode,scenario,messages,bag] [--seed S]`` tries ``N`` inputs
per kind (:mod:`cnc_tools.bench.fuzz_inputs` says how each kind is made and what nonsense is for it) and
prints per kind: inputs tried, those accepted as sensible, tracebacks (an exception outside the
:class:`CncError` family), hangs (an input taking more than :data:`HANG_BOUND_S`), silent acceptances of
nonsense, and whether the goal
0 / 0 / 0 is met, with the first few findings of each sort. A plain seeded generator, not hypothesis: it
makes 100 000 inputs in the time hypothesis makes a few thousand (the tests use hypothesis).
"""
from __future__ import annotations

import argparse
import random
import signal
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from types import FrameType
from typing import Any

from cnc_contour_control.core.config import require_choice
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.bench import fuzz_inputs as inputs
from cnc_tools.runs.progress import track

#: An input running longer than this is a hang [s].
HANG_BOUND_S = 2.0
#: Inputs per kind by default (a quarter for the slow kinds): about a minute for the four kinds.
DEFAULT_COUNT = 5000
#: Findings of each sort printed per kind.
SHOWN = 3


@dataclass(frozen=True)
class Kind:
    """One input kind: a generator from a seeded ``random.Random``, and the check of one input."""

    generate: Callable[[random.Random], Any]
    check: Callable[[Any], str | None]
    #: Inputs per kind by default are divided by this (a kind whose input is slow).
    cost: int = 1


KINDS: dict[str, Kind] = {
    "gcode": Kind(inputs.gcode_input, inputs.check_gcode),
    "scenario": Kind(inputs.scenario_input, inputs.check_scenario, cost=4),
    "messages": Kind(inputs.message_input, inputs.check_message),
    "bag": Kind(inputs.bag_input, inputs.check_bag, cost=4),
}


class _Hang(BaseException):
    """The time bound of one input ran out (a BaseException: no ``except Exception`` of the code swallows it)."""


def _alarm(signum: int, frame: FrameType | None) -> None:
    raise _Hang


@dataclass
class Tally:
    """What the inputs of one kind gave."""

    tried: int = 0
    accepted: int = 0
    tracebacks: list[str] = field(default_factory=list)
    hangs: list[str] = field(default_factory=list)
    nonsense: list[str] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def met(self) -> bool:
        """The goal: no traceback, no hang, no nonsense accepted."""
        return not (self.tracebacks or self.hangs or self.nonsense)


def run_one(kind: Kind, case: Any, tally: Tally) -> None:
    """Check one input under the time bound and count what it gave."""
    tally.tried += 1
    start_s = time.perf_counter()
    signal.setitimer(signal.ITIMER_REAL, HANG_BOUND_S)
    try:
        finding = kind.check(case)
    except _Hang:
        tally.hangs.append(f"{_short(case)} ran over {HANG_BOUND_S} s")
        return
    except Exception:
        tally.tracebacks.append(f"{_short(case)}\n{traceback.format_exc(limit=-3)}")
        return
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
    if time.perf_counter() - start_s > HANG_BOUND_S:
        tally.hangs.append(f"{_short(case)} took {time.perf_counter() - start_s:.1f} s")
    if finding:
        tally.nonsense.append(finding)
    elif finding == "":
        tally.accepted += 1


def _short(case: Any) -> str:
    text = repr(case)
    return text if len(text) < 300 else text[:300] + "..."


def fuzz_kind(kind: Kind, count: int, seed: int) -> Tally:
    """Run ``count`` inputs of one kind from ``seed``."""
    rng, tally = random.Random(seed), Tally()
    previous = signal.signal(signal.SIGALRM, _alarm)
    start_s = time.perf_counter()
    try:
        for _ in track(range(count), "fuzz inputs"):
            run_one(kind, kind.generate(rng), tally)
    finally:
        signal.signal(signal.SIGALRM, previous)
        tally.seconds = time.perf_counter() - start_s
    return tally


def add_options(parser: argparse.ArgumentParser) -> None:
    """``--count``, ``--kinds`` and ``--seed`` (bench fuzz)."""
    parser.add_argument("--count", type=int, help=f"inputs per kind (bench fuzz; default {DEFAULT_COUNT}, "
                        "a quarter for scenario and bag)")
    parser.add_argument("--kinds", help=f"comma-separated kinds (bench fuzz; default all: {','.join(KINDS)})")
    parser.add_argument("--seed", type=int, default=0, help="seed of the inputs (bench fuzz; default 0)")


def _plan(options: argparse.Namespace) -> dict[str, int]:
    """Inputs per chosen kind."""
    names = [n.strip() for n in (getattr(options, "kinds", None) or ",".join(KINDS)).split(",") if n.strip()]
    for name in names:
        require_choice("kinds", name, KINDS)
    count = getattr(options, "count", None)
    if count is not None and count < 1:
        from cnc_contour_control.core.errors import ConfigError

        raise ConfigError(f"count must be >= 1, got {count}")
    quick = getattr(options, "quick", False)
    default = DEFAULT_COUNT // (10 if quick else 1)
    return {name: count or max(default // KINDS[name].cost, 1) for name in names}


def fuzz_bench(options: argparse.Namespace) -> int:
    """Fuzz each chosen kind; print the table and the first findings; 1 when the goal is not met."""
    plan, seed = _plan(options), int(getattr(options, "seed", 0) or 0)
    tallies = {name: fuzz_kind(KINDS[name], count, seed) for name, count in track(plan.items(), "fuzz kinds")}
    print(f"fuzz: seed {seed}, hang bound {HANG_BOUND_S} s")
    print(format_table(["kind", "inputs", "accepted (sensible)", "tracebacks", "hangs", "nonsense accepted",
                        "seconds", "goal 0/0/0"],
                       [[name, t.tried, t.accepted, len(t.tracebacks), len(t.hangs), len(t.nonsense),
                         round(t.seconds, 1), "met" if t.met else "NOT MET"] for name, t in tallies.items()]))
    for name, tally in tallies.items():
        for sort, found in (("traceback", tally.tracebacks), ("hang", tally.hangs), ("nonsense", tally.nonsense)):
            for finding in found[:SHOWN]:
                print(f"--- {name} {sort}: {finding}")
    write_json(getattr(options, "json", None), {
        "bench": "fuzz", "seed": seed, "hang_bound_s": HANG_BOUND_S, "machine": machine(),
        "kinds": {name: {"inputs": t.tried, "accepted": t.accepted, "tracebacks": len(t.tracebacks),
                         "hangs": len(t.hangs), "nonsense": len(t.nonsense), "seconds": t.seconds, "met": t.met,
                         "examples": (t.tracebacks + t.hangs + t.nonsense)[:SHOWN]} for name, t in tallies.items()}})
    return 0 if all(t.met for t in tallies.values()) else 1
