"""Bench ``compose``: the 1 kHz loop composed in one process, against separate processes and the engine.

Measured side by side in one run on paper 001's circle with the window
estimator and the neural compensator (``scenarios/paper001_circle_neural.yaml``,
T = 1 ms, six nodes and the recorder):

1. lockstep: the engine and the node graph recorded with ``--compose none``
   (seven processes), ``loop`` (the six loop nodes in one process, the
   recorder apart), ``all`` (one process) and ``all-dds`` (``all`` with the
   local bus off: every message over DDS, as before the bus), and ``none-rclpy`` and
   ``all-rclpy`` (messages converted by rclpy's own serialization, ``CNC_FAST_CDR=0``,
   as before the generated codecs of ``nodes/fast_cdr.py``). Each round runs them in a
   rotated order, so all see the same machine load; the figures are the
   medians over the rounds of the wall time per tick (the plant's summary:
   first tick to last, start-up excluded), the real-time factor and the
   ratios to the engine and to separate processes, and the CPU time (user +
   system) of the run's processes per tick, less that of a 2-tick run of the
   same side (start-up and shut-down). Goal: the composed loop at least
   :data:`RTF_GOAL` times real time.
2. real time: the graph recorded with ``--compose none``, ``loop`` and ``all``; the
   share of late commands (the plant's ``late_commands`` / (ticks · axes),
   goal <= :data:`LATE_SHARE_GOAL`) and the period error (the recorded
   ``joint_states`` stamps advance by the measured period: p50 and p99 of
   |period - T|).

The 1-minute load average is printed at the start and the end: the machine
is shared and absolute figures swing; the ratios are measured in one run.
"""
from __future__ import annotations

import argparse
import os
import statistics
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.core.errors import CncError
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.bagio.bag import read_bag
from cnc_tools.bench.lockstep import children_cpu_s
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.graph import run_graph
from cnc_tools.runs.progress import track
from cnc_tools.runs.scenario import Scenario, load_scenario

SCENARIO = "scenarios/paper001_circle_neural.yaml"
#: Goal: the composed loop runs lockstep at T = 1 ms at least this fast against real time.
RTF_GOAL = 1.0
#: Goal: in real time, at most this share of the commands is late.
LATE_SHARE_GOAL = 0.01
#: Lockstep sides: the engine, then the graph's compose modes.
LOCKSTEP_SIDES = ("engine", "none", "none-rclpy", "loop", "all", "all-rclpy", "all-dds")
REALTIME_SIDES = ("none", "loop", "all")
#: The switches a graph side sets for its processes (inherited from this one): the local bus and the fast CDR codecs.
SWITCHES = ("CNC_LOCAL_BUS", "CNC_FAST_CDR")
#: Graph side -> (compose mode, switches off): ``-rclpy`` converts messages with rclpy's own serialization
#: (``CNC_FAST_CDR=0``), ``all-dds`` sends every message over DDS (``CNC_LOCAL_BUS=0``).
GRAPH_SIDES: dict[str, tuple[str, tuple[str, ...]]] = {
    "none": ("none", ()), "none-rclpy": ("none", ("CNC_FAST_CDR",)), "loop": ("loop", ()), "all": ("all", ()),
    "all-rclpy": ("all", ("CNC_FAST_CDR",)), "all-dds": ("all", ("CNC_LOCAL_BUS",))}


@contextmanager
def switches_env(off: tuple[str, ...]) -> Iterator[None]:
    """Every switch of :data:`SWITCHES` on ("1") but those in ``off`` ("0") for the processes started meanwhile."""
    before = {name: os.environ.get(name) for name in SWITCHES}
    os.environ.update({name: "0" if name in off else "1" for name in SWITCHES})
    try:
        yield
    finally:
        for name, value in before.items():
            if value is None:
                os.environ.pop(name)
            else:
                os.environ[name] = value


def graph_run(side: str, scenario: Scenario, run_dir: Path, timeout_s: float) -> Any:
    """The recorded graph run of ``side`` (its compose mode and switches)."""
    mode, off = GRAPH_SIDES[side]
    with switches_env(off):
        return run_graph(scenario, run_dir, record=True, compose=mode, timeout_s=timeout_s)


@dataclass(frozen=True)
class Plan:
    """How long the bench measures."""

    rounds: int
    lockstep_duration_s: float | None  # None: the scenario's own
    realtime_duration_s: float


FULL = Plan(3, None, 3.0)
QUICK = Plan(1, 0.3, 1.0)


@dataclass(frozen=True)
class LockstepFigures:
    """One lockstep run."""

    side: str
    ticks: int
    wall_time_s: float
    real_time_factor: float
    cpu_s: float  # the run's processes, start-up included (0 for the engine: this process)


@dataclass(frozen=True)
class RealtimeFigures:
    """One real-time run."""

    side: str
    status: str
    ticks: int
    late_share: float
    period_error_p50_s: float | None
    period_error_p99_s: float | None


def bench_scenario(run_dir: Path, mode: str, duration_s: float | None) -> Scenario:
    """The bench's scenario in ``mode``, its learned state saved into ``run_dir`` (not the project's bags/)."""
    overrides: dict[str, Any] = {"mode": mode, "compensator": {"state_out": str(run_dir / "state.npz")}}
    if duration_s is not None:
        overrides["duration_s"] = duration_s
    return load_scenario(project_root() / SCENARIO, overrides)


def lockstep_run(side: str, run_dir: Path, duration_s: float | None) -> LockstepFigures:
    """One lockstep run of ``side`` (the engine, or the graph in that compose mode)."""
    scenario = bench_scenario(run_dir, "lockstep", duration_s)
    before_s = children_cpu_s()
    if side == "engine":
        summary = run_engine(scenario).summary
    else:
        summary = graph_run(side, scenario, run_dir, 1800.0).summary
        if summary.get("faults"):
            raise CncError(f"bench compose: the {side} run faulted: {summary['faults']}")
    return LockstepFigures(side, int(summary["ticks"]), float(summary["wall_time_s"]),
                           float(summary["real_time_factor"]), children_cpu_s() - before_s)


def startup_cpu_s(run_dir: Path) -> dict[str, float]:
    """CPU seconds of starting, connecting and stopping each graph side: a run of 2 ticks."""
    return {side: lockstep_run(side, run_dir / f"startup_{side}", 0.001).cpu_s for side in LOCKSTEP_SIDES[1:]}


def realtime_run(side: str, run_dir: Path, duration_s: float) -> RealtimeFigures:
    """One real-time run; a run that faults is reported with what it reached, not raised."""
    scenario = bench_scenario(run_dir, "realtime", duration_s)
    try:
        result = graph_run(side, scenario, run_dir, 600.0)
        summary, status = result.summary, "faulted" if result.faults else "finished"
    except CncError as err:
        return RealtimeFigures(side, f"died: {err}", 0, float("nan"), None, None)
    ticks = int(summary["ticks"])
    late_share = int(summary["late_commands"]) / max(ticks * len(scenario.axes), 1)
    p50, p99 = period_errors(run_dir / "bag", scenario.sample_time_s)
    return RealtimeFigures(side, status, ticks, late_share, p50, p99)


def period_errors(bag: Path, sample_time_s: float) -> tuple[float | None, float | None]:
    """p50 and p99 of |period - T| [s] from the recorded joint_states stamps (None if the bag cannot be read)."""
    try:
        stamps = read_bag(bag, commands=False).joint_states.stamp_ns
    except (CncError, OSError, ValueError, KeyError):
        return None, None
    errors = np.abs(np.diff(stamps.astype(np.int64)).astype(np.float64) * 1e-9 - sample_time_s)
    if errors.size == 0:
        return None, None
    return float(np.percentile(errors, 50)), float(np.percentile(errors, 99))


def lockstep_rounds(run_dir: Path, plan: Plan) -> list[list[LockstepFigures]]:
    """``plan.rounds`` rounds of every side, each round in a rotated order."""
    rounds = []
    for r in track(range(plan.rounds), "compose lockstep rounds"):
        order = LOCKSTEP_SIDES[r % len(LOCKSTEP_SIDES):] + LOCKSTEP_SIDES[:r % len(LOCKSTEP_SIDES)]
        figures = {}
        for side in order:
            print(f"  round {r + 1}/{plan.rounds}: lockstep {side} ...", flush=True)
            figures[side] = lockstep_run(side, run_dir / f"lockstep_{side}_{r}", plan.lockstep_duration_s)
        rounds.append([figures[side] for side in LOCKSTEP_SIDES])
    return rounds


def lockstep_table(rounds: list[list[LockstepFigures]], startup_s: dict[str, float]) -> list[dict[str, Any]]:
    """Per side: median wall per tick, RTF and CPU per tick over the rounds, and the ratios to the engine and
    ``none``."""
    per_tick = {side: statistics.median(r[i].wall_time_s / r[i].ticks for r in rounds)
                for i, side in enumerate(LOCKSTEP_SIDES)}
    rows = []
    for i, side in enumerate(LOCKSTEP_SIDES):
        rtf = statistics.median(r[i].real_time_factor for r in rounds)
        cpu = statistics.median(max(r[i].cpu_s - startup_s.get(side, 0.0), 0.0) / r[i].ticks for r in rounds)
        rows.append({"side": side, "ticks": rounds[0][i].ticks, "wall_per_tick_s": per_tick[side],
                     "cpu_per_tick_s": None if side == "engine" else cpu,
                     "real_time_factor": rtf, "ratio_to_engine": per_tick[side] / per_tick["engine"],
                     "ratio_to_separate": per_tick[side] / per_tick["none"],
                     "goal_met": None if side in ("engine", "none") else rtf >= RTF_GOAL})
    return rows


def compose_bench(options: argparse.Namespace) -> int:
    """Lockstep rounds and real-time runs; print the tables; write JSON if asked."""
    plan = QUICK if options.quick else FULL
    load_at_start = machine()["load_average_1min"]
    run_dir = options.out or project_root() / "bags" / "bench" / "compose" / timestamp()
    print(f"compose bench ({'quick' if options.quick else 'full'}) on {SCENARIO}; run files in {run_dir}", flush=True)
    print("  start-up of each graph side (2 ticks) ...", flush=True)
    startup_s = startup_cpu_s(run_dir)
    rounds = lockstep_rounds(run_dir, plan)
    realtime = []
    for side in track(REALTIME_SIDES, "compose real-time runs"):
        print(f"  real time {side} ...", flush=True)
        realtime.append(realtime_run(side, run_dir / f"realtime_{side}", plan.realtime_duration_s))
    figures = {"bench": "compose", "quick": options.quick, "scenario": SCENARIO, "machine": machine(),
               "rounds": [[asdict(f) for f in r] for r in rounds], "startup_cpu_s": startup_s,
               "lockstep": lockstep_table(rounds, startup_s),
               "realtime": [{**asdict(f), "goal_met": f.late_share <= LATE_SHARE_GOAL} for f in realtime]}
    figures["machine"]["load_average_1min_at_start"] = load_at_start
    print_figures(figures)
    write_json(options.json, figures)
    return 0


def _us(value: float | None) -> object:
    return "-" if value is None else value * 1e6


def print_figures(figures: dict[str, Any]) -> None:
    """The two tables of the bench, with the machine's load."""
    m = figures["machine"]
    print(f"\nmachine: {m['cpus']} cores, {m['cpu']}, Python {m['python']}, {m['rmw']}; 1-min load average "
          f"{m['load_average_1min_at_start']:.2f} at start, {m['load_average_1min']:.2f} at end")
    print(f"\nlockstep, T = 1 ms, {figures['scenario']} (6 nodes + recorder), medians of {len(figures['rounds'])} "
          f"round(s); goal composed RTF >= {RTF_GOAL:g}")
    print(format_table(["side", "ticks", "wall/tick [us]", "CPU/tick [us]", "RTF", "/ engine", "/ separate", "goal"], [
        [r["side"], r["ticks"], r["wall_per_tick_s"] * 1e6, _us(r["cpu_per_tick_s"]), r["real_time_factor"],
         r["ratio_to_engine"],
         r["ratio_to_separate"], "-" if r["goal_met"] is None else goal_text(r["goal_met"])]
        for r in figures["lockstep"]]))
    print(f"\nreal time, T = 1 ms; goal late share <= {LATE_SHARE_GOAL:.0%}")
    print(format_table(["compose", "status", "ticks", "late share", "|period err| p50 [us]", "p99 [us]", "goal"], [
        [r["side"], r["status"], r["ticks"], r["late_share"], _us(r["period_error_p50_s"]),
         _us(r["period_error_p99_s"]), goal_text(r["goal_met"])] for r in figures["realtime"]]))
