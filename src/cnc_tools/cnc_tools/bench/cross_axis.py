"""Bench ``cross-axis``: the node graph with the estimator and the compensator in the loop, against the graph without.

Measured side by side in one run, at T = 1 ms on the paper-000 circle
(``scenarios/paper000_circle_high.yaml``): the core graph (plant,
interpolator, two servos) and the six-node graph (plus the window estimator
and the neural compensator, learning). A tick's critical path grows from
three hops (plant → interpolator → servo → plant) to five (→ estimator →
compensator → servo), so the goal is a wall time per tick at most
:data:`WALL_RATIO_GOAL` times the core graph's. The two graphs alternate,
round by round and in swapped order, so both see the same machine load; the
ratios are of the medians. The CPU time all node processes spend per tick is
printed beside (the cost of starting and stopping them taken out by a 2-tick
run of each graph), and each node's own CPU per tick: a thread reads
``utime + stime`` of every pid in the run's ``pids.json`` from
``/proc/<pid>/stat`` every 50 ms and keeps the last reading before the
process ends, less the same node's CPU in the 2-tick run.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import threading
from dataclasses import asdict
from pathlib import Path
from typing import Any

from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.bench.lockstep import GraphFigures, graph_run, measure_graph
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.progress import track
from cnc_tools.runs.scenario import Scenario, load_scenario

SCENARIO = "scenarios/paper000_circle_high.yaml"
SAMPLE_TIME_S = 0.001
#: Goal: the six-node graph's wall time per tick at most this many times the core graph's.
WALL_RATIO_GOAL = 1.6
#: The cross-axis stages the bench adds (the paper-001 pair; a small learning rate: the loop must stay sane).
CROSS_AXIS = {"estimator": {"method": "window"}, "compensator": {"method": "neural"}}


def scenarios(duration_s: float) -> dict[str, Scenario]:
    """The core graph and the graph with both cross-axis stages, at T = 1 ms for ``duration_s``."""
    base = load_scenario(project_root() / SCENARIO, {"sample_time_s": SAMPLE_TIME_S, "duration_s": duration_s})
    return {"core": base, "cross-axis": base.variant(CROSS_AXIS)}


def _startup_cpu_s(scenario: Scenario, run_dir: Path) -> tuple[float, dict[str, float]]:
    """CPU seconds of starting, connecting and stopping ``scenario``'s graph (a run of 2 ticks): all, and per node."""
    with NodeCpu(run_dir) as nodes:
        total_s = graph_run(scenario.variant({"duration_s": SAMPLE_TIME_S}), run_dir)[1]
    return total_s, dict(nodes.cpu_s)


class NodeCpu:
    """While a graph runs in ``run_dir``: the CPU seconds each node process has used so far (Linux ``/proc``)."""

    def __init__(self, run_dir: Path, period_s: float = 0.05) -> None:
        self.run_dir, self.period_s = run_dir, period_s
        self.cpu_s: dict[str, float] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def __enter__(self) -> NodeCpu:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def _sample(self) -> None:
        ticks_per_s = os.sysconf("SC_CLK_TCK")
        while not self._stop.wait(self.period_s):
            try:
                pids = json.loads((self.run_dir / "pids.json").read_text())["nodes"]
            except (OSError, ValueError, KeyError):
                continue  # not written yet
            for name, pid in pids.items():
                try:
                    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
                except OSError:
                    continue  # ended: keep its last reading
                self.cpu_s[name] = (int(fields[11]) + int(fields[12])) / ticks_per_s


def _measure(scenario: Scenario, run_dir: Path, startup: tuple[float, dict[str, float]]
             ) -> tuple[GraphFigures, dict[str, float]]:
    """One graph run: its figures and each node's CPU seconds per tick (its 2-tick run's CPU taken out)."""
    with NodeCpu(run_dir) as nodes:
        figures = measure_graph(scenario, run_dir, startup[0])
    return figures, {name: max(cpu_s - startup[1].get(name, 0.0), 0.0) / figures.ticks
                     for name, cpu_s in nodes.cpu_s.items()}


def cross_axis_bench(options: argparse.Namespace) -> int:
    """Run the bench and print (and optionally write) the figures; 0 unless it failed."""
    quick = bool(getattr(options, "quick", False))
    rounds, duration_s = (2, 1.0) if quick else (5, 3.0)
    cases = scenarios(duration_s)
    run_dir = project_root() / "bags" / f"bench-cross-axis-{timestamp()}"
    startup = {name: _startup_cpu_s(s, run_dir / f"{name}-startup") for name, s in cases.items()}
    figures: dict[str, list[GraphFigures]] = {name: [] for name in cases}
    per_node: dict[str, list[dict[str, float]]] = {name: [] for name in cases}
    for k in track(range(rounds), "cross-axis rounds"):
        order = list(cases) if k % 2 == 0 else list(reversed(cases))
        print(f"  round {k + 1}/{rounds}: {' then '.join(order)}", flush=True)
        for name in order:
            graph, nodes = _measure(cases[name], run_dir / f"{name}-{k}", startup[name])
            figures[name].append(graph)
            per_node[name].append(nodes)
    result = collect(quick, figures)
    result["node_cpu_per_tick_s"] = {name: {node: statistics.median(r[node] for r in runs if node in r)
                                            for node in runs[0]} for name, runs in per_node.items()}
    print_figures(result)
    if getattr(options, "json", None):
        write_json(Path(options.json), result)
    return 0


def collect(quick: bool, figures: dict[str, list[GraphFigures]]) -> dict[str, Any]:
    """Medians per graph and the ratios of the six-node graph to the core graph."""
    medians = {name: {"wall_per_tick_s": statistics.median(f.wall_per_tick_s for f in runs),
                      "cpu_per_tick_s": statistics.median(f.cpu_per_tick_s for f in runs),
                      "ticks": runs[0].ticks, "runs": len(runs)} for name, runs in figures.items()}
    core, cross = medians["core"], medians["cross-axis"]
    return {"bench": "cross-axis", "quick": quick, "machine": machine(), "sample_time_s": SAMPLE_TIME_S,
            "medians": medians, "runs": {name: [asdict(f) for f in runs] for name, runs in figures.items()},
            "wall_ratio": cross["wall_per_tick_s"] / core["wall_per_tick_s"],
            "cpu_ratio": cross["cpu_per_tick_s"] / core["cpu_per_tick_s"], "wall_ratio_goal": WALL_RATIO_GOAL}


def print_figures(result: dict[str, Any]) -> None:
    """The table of medians and the ratios against the goal."""
    rows = [[name, m["ticks"], m["runs"], round(m["wall_per_tick_s"] * 1e6), round(m["cpu_per_tick_s"] * 1e6)]
            for name, m in result["medians"].items()]
    print(format_table(["graph at T = 1 ms", "ticks", "runs", "wall µs/tick", "CPU µs/tick"], rows))
    nodes = result.get("node_cpu_per_tick_s", {})
    if nodes:
        names = sorted({node for graph in nodes.values() for node in graph})
        print(format_table(["node CPU µs/tick", *nodes],
                           [[node, *(round(nodes[g][node] * 1e6) if node in nodes[g] else "-" for g in nodes)]
                            for node in names]))
    print(f"wall per tick, six nodes / four: {result['wall_ratio']:.2f} "
          f"(goal <= {WALL_RATIO_GOAL}: {goal_text(result['wall_ratio'] <= WALL_RATIO_GOAL)}); "
          f"CPU per tick: {result['cpu_ratio']:.2f}; 1-min load {result['machine'].get('load_average_1min')}")
