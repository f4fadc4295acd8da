"""Bench ``lockstep``: what a lockstep tick costs through DDS, against a bare rclpy hop and the engine.

Measured side by side in one run, on the paper-000 circle
(``scenarios/paper000_circle_high.yaml``, two axes):

1. the node graph (:func:`cnc_tools.runs.graph.run_graph`) at T = 10 ms and 1 ms:
   ticks, wall time and real-time factor from the plant's summary, wall time
   per tick, and per hop: a tick's critical path is plant → interpolator →
   servo → plant, :data:`HOPS` = 3 hops (the servos run in parallel, and
   ``joint_states`` reaches them while the interpolator works). Also the CPU
   time (user + system) all node processes spend per tick, with the cost of
   starting and stopping them taken out by a 2-tick run, and the cores that
   keeps busy (CPU time / wall time);
2. a bare rclpy round trip between two processes
   (:mod:`cnc_tools.bench.pingpong`, the graph's QoS and executor), with a
   ``Reference`` and with a ``Float64``; one hop = median round trip / 2;
3. the ratio per-hop overhead / bare hop (goal <= :data:`HOP_RATIO_GOAL`);
   beside it, a bare relay graph (:mod:`cnc_tools.bench.relay`: the graph's
   four processes, topics, message types, QoS and executor, no suite code),
   per hop = wall per tick / :data:`HOPS`, and the two ratios that split the
   goal's: graph / relay (what the suite's nodes add) and relay / ping-pong
   (what the topology costs on this machine);
4. the in-process engine's real-time factor at T = 1 ms and 10 ms, median of
   several runs (goal at 1 ms >= :data:`ENGINE_RTF_GOAL`).
"""
from __future__ import annotations

import argparse
import resource
import statistics
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.bench.hop_terms import HOP_RATIO_GOAL, HOPS, SCENARIO, scenario_at
from cnc_tools.bench.peers import round_trips
from cnc_tools.bench.relay import relay_ticks
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.graph import run_graph
from cnc_tools.runs.progress import track
from cnc_tools.runs.scenario import Scenario

#: Goal: the engine runs two axes at T = 1 ms at least this much faster than real time.
ENGINE_RTF_GOAL = 100.0
SAMPLE_TIMES_S = (0.01, 0.001)


@dataclass(frozen=True)
class Plan:
    """How long a bench run measures."""

    graph_duration_s: dict[float, float | None]  # per T; None: the scenario's duration
    pingpong_iterations: int
    pingpong_warmup: int
    engine_repeats: int
    relay_ticks: int = 6000
    relay_warmup: int = 500


FULL = Plan({0.01: None, 0.001: None}, 2000, 200, 7)
QUICK = Plan({0.01: 2.0, 0.001: 1.0}, 500, 50, 3, 1000, 100)


@dataclass(frozen=True)
class GraphFigures:
    """One node-graph run."""

    sample_time_s: float
    ticks: int
    simulated_time_s: float
    wall_time_s: float
    real_time_factor: float
    wall_per_tick_s: float
    per_hop_s: float
    cpu_per_tick_s: float
    cores_busy: float


@dataclass(frozen=True)
class HopFigures:
    """The bare rclpy round trip of one message type."""

    message: str
    iterations: int
    round_trip_median_s: float
    round_trip_p90_s: float
    one_way_hop_s: float


@dataclass(frozen=True)
class EngineFigures:
    """Repeated engine runs at one sample time."""

    sample_time_s: float
    ticks: int
    repeats: int
    real_time_factor_median: float
    real_time_factor_best: float
    wall_per_tick_median_s: float


def children_cpu_s() -> float:
    """User + system CPU seconds of this process's children that have been reaped."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def graph_run(scenario: Scenario, run_dir: Path) -> tuple[dict[str, Any], float]:
    """The plant's summary of one node-graph run and the CPU seconds its processes used."""
    before = children_cpu_s()
    summary = run_graph(scenario, run_dir).summary
    return summary, children_cpu_s() - before


def startup_cpu_s(run_dir: Path) -> float:
    """CPU seconds of starting, connecting and stopping the graph: a run of 2 ticks."""
    return graph_run(scenario_at(0.01, 0.01), run_dir)[1]


def measure_graph(scenario: Scenario, run_dir: Path, startup_s: float) -> GraphFigures:
    """Run the node graph once and derive the per-tick and per-hop wall time and the CPU per tick."""
    summary, cpu_s = graph_run(scenario, run_dir)
    ticks, wall_s = int(summary["ticks"]), float(summary["wall_time_s"])
    per_tick, tick_cpu_s = wall_s / ticks, max(cpu_s - startup_s, 0.0)
    return GraphFigures(scenario.sample_time_s, ticks, float(summary["simulated_time_s"]), wall_s,
                        float(summary["real_time_factor"]), per_tick, per_tick / HOPS,
                        tick_cpu_s / ticks, tick_cpu_s / wall_s)


def measure_hop(run_dir: Path, message: str, plan: Plan) -> HopFigures:
    """Median and 90th percentile of the bare round trip; one hop is half the median."""
    times = sorted(round_trips(run_dir, message, plan.pingpong_iterations, plan.pingpong_warmup))
    median = statistics.median(times)
    return HopFigures(message, len(times), median, times[int(0.9 * (len(times) - 1))], median / 2.0)


def measure_engine(scenario: Scenario, repeats: int) -> EngineFigures:
    """Real-time factor of ``repeats`` engine runs (median and best)."""
    results = [run_engine(scenario) for _ in range(repeats)]
    factors = [r.summary["real_time_factor"] for r in results]
    return EngineFigures(scenario.sample_time_s, results[0].ticks, repeats, statistics.median(factors),
                         max(factors), statistics.median(r.summary["wall_time_s"] / r.ticks for r in results))


def lockstep_bench(options: argparse.Namespace) -> int:
    """Measure the node graph, the bare hop and the engine; print the table; write JSON if asked."""
    plan = QUICK if options.quick else FULL
    load_at_start = machine()["load_average_1min"]
    run_dir = options.out or project_root() / "bags" / "bench" / "lockstep" / timestamp()
    print(f"lockstep bench ({'quick' if options.quick else 'full'}) on {SCENARIO}; run files in {run_dir}", flush=True)
    print("  node graph start-up (2 ticks) ...", flush=True)
    startup_s = startup_cpu_s(run_dir / "graph_startup")
    graph = []
    for t in track(SAMPLE_TIMES_S, "lockstep graph runs"):
        print(f"  node graph at T = {t * 1e3:g} ms ...", flush=True)
        scenario = scenario_at(t, plan.graph_duration_s[t])
        graph.append(measure_graph(scenario, run_dir / f"graph_T{t * 1e3:g}ms", startup_s))
    print("  bare rclpy ping-pong ...", flush=True)
    hops = [measure_hop(run_dir / "pingpong", message, plan) for message in ("reference", "float64")]
    print("  bare relay graph ...", flush=True)
    relay_per_tick_s = relay_ticks(run_dir / "relay", plan.relay_ticks, plan.relay_warmup)
    print("  engine ...", flush=True)
    engine = [measure_engine(scenario_at(t, None), plan.engine_repeats) for t in SAMPLE_TIMES_S]
    figures = collect(options.quick, graph, hops, engine, relay_per_tick_s)
    figures["machine"]["load_average_1min_at_start"] = load_at_start
    print_figures(figures)
    write_json(options.json, figures)
    return 0


def collect(quick: bool, graph: list[GraphFigures], hops: list[HopFigures],
            engine: list[EngineFigures], relay_per_tick_s: float) -> dict[str, Any]:
    """Every figure of the run, with the ratios and goals, as plain types."""
    bare, relay_hop = hops[0].one_way_hop_s, relay_per_tick_s / HOPS
    ratios = [{"sample_time_s": g.sample_time_s, "per_hop_s": g.per_hop_s, "bare_hop_s": bare,
               "ratio": g.per_hop_s / bare, "goal": HOP_RATIO_GOAL, "met": g.per_hop_s / bare <= HOP_RATIO_GOAL,
               "relay_hop_s": relay_hop, "graph_over_relay": g.per_hop_s / relay_hop}
              for g in graph]
    at_1ms = next(e for e in engine if e.sample_time_s == 0.001)
    return {
        "bench": "lockstep", "quick": quick, "scenario": SCENARIO, "machine": machine(), "hops_per_tick": HOPS,
        "graph": [asdict(g) for g in graph], "bare_hop": [asdict(h) for h in hops],
        "hop_ratio": ratios, "engine": [asdict(e) for e in engine],
        "relay": {"wall_per_tick_s": relay_per_tick_s, "per_hop_s": relay_hop, "relay_over_bare": relay_hop / bare},
        "engine_goal": {"sample_time_s": 0.001, "real_time_factor_min": ENGINE_RTF_GOAL,
                        "measured_median": at_1ms.real_time_factor_median,
                        "met": at_1ms.real_time_factor_median >= ENGINE_RTF_GOAL},
    }


def print_figures(figures: dict[str, Any]) -> None:
    """The four tables of the bench."""
    m = figures["machine"]
    print(f"\nmachine: {m['cpus']} cores, {m['cpu']}, Python {m['python']}, {m['rmw']}; 1-min load average "
          f"{m['load_average_1min_at_start']:.2f} at start, {m['load_average_1min']:.2f} at end")
    print(f"\nnode graph, {figures['scenario']} (2 axes), {HOPS} hops per tick "
          "(plant -> interpolator -> servo -> plant)")
    print(format_table(["T [ms]", "ticks", "wall [s]", "RTF", "wall/tick [us]", "per hop [us]", "CPU/tick [us]",
                        "cores busy"], [
        [g["sample_time_s"] * 1e3, g["ticks"], g["wall_time_s"], g["real_time_factor"], g["wall_per_tick_s"] * 1e6,
         g["per_hop_s"] * 1e6, g["cpu_per_tick_s"] * 1e6, g["cores_busy"]] for g in figures["graph"]]))
    print("\nbare rclpy hop, 2 processes, LOCKSTEP_QOS, the nodes' executor (make_executor)")
    print(format_table(["message", "round trips", "median RTT [us]", "p90 RTT [us]", "one-way hop [us]"], [
        [h["message"], h["iterations"], h["round_trip_median_s"] * 1e6, h["round_trip_p90_s"] * 1e6,
         h["one_way_hop_s"] * 1e6] for h in figures["bare_hop"]]))
    print(f"\nper-hop overhead / bare hop (Reference), goal <= {HOP_RATIO_GOAL:g}")
    print(format_table(["T [ms]", "per hop [us]", "bare hop [us]", "ratio", "goal"], [
        [r["sample_time_s"] * 1e3, r["per_hop_s"] * 1e6, r["bare_hop_s"] * 1e6, r["ratio"], goal_text(r["met"])]
        for r in figures["hop_ratio"]]))
    relay = figures["relay"]
    print(f"\nbare relay graph (the graph's 4 processes, topics, types, QoS, executor; no suite code): "
          f"{relay['wall_per_tick_s'] * 1e6:.0f} us/tick, {relay['per_hop_s'] * 1e6:.0f} us/hop, "
          f"{relay['relay_over_bare']:.2f} bare hops (what the topology costs)")
    print(format_table(["T [ms]", "graph per hop [us]", "relay per hop [us]", "graph / relay (what the nodes add)"], [
        [r["sample_time_s"] * 1e3, r["per_hop_s"] * 1e6, r["relay_hop_s"] * 1e6, r["graph_over_relay"]]
        for r in figures["hop_ratio"]]))
    goal = figures["engine_goal"]
    print(f"\nengine (in-process), 2 axes; goal at T = 1 ms: RTF >= {ENGINE_RTF_GOAL:g} (median): "
          f"{goal_text(goal['met'])}")
    print(format_table(["T [ms]", "ticks", "runs", "RTF median", "RTF best", "wall/tick [us]"], [
        [e["sample_time_s"] * 1e3, e["ticks"], e["repeats"], e["real_time_factor_median"],
         e["real_time_factor_best"], e["wall_per_tick_median_s"] * 1e6] for e in figures["engine"]]))
