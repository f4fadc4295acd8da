"""Bench ``hops``: the separate-process graph's hop against a bare rclpy hop, in interleaved rounds.

On a shared machine one ping-pong and one graph run a minute apart can
differ by 2× in absolute terms (``bench lockstep`` measures each side
once). This bench measures the three sides of the hop ratio in every round,
in a rotated order, and judges the goal by the median of the per-round
ratios:

- **bare**: a ``Reference`` ping-pong between two processes
  (:mod:`cnc_tools.bench.pingpong`); one hop = median round trip / 2;
- **relay**: the bare relay graph (:mod:`cnc_tools.bench.relay`: the graph's
  four processes, topics, types, QoS and executor, no suite code); per hop =
  wall per tick / :data:`~cnc_tools.bench.lockstep.HOPS`;
- **graph**: the node graph at T = 1 ms (:func:`cnc_tools.runs.graph.run_graph`,
  one process per node); per hop = the plant's wall per tick / ``HOPS``.

With ``--dds-profile NAME=PATH`` (repeatable) every round runs all three
sides under each Fast DDS profile, so that two transports are compared side
by side; the default is the shipped profile alone.
"""
from __future__ import annotations

import argparse
import os
import statistics
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.bench.hop_terms import HOP_RATIO_GOAL, HOPS, scenario_at
from cnc_tools.runs.dds import profile_path
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.progress import track

PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
SHIPPED = "shipped"


@dataclass(frozen=True)
class Plan:
    """How much each side measures per round."""

    rounds: int
    round_trips: int = 1000
    pingpong_warmup: int = 100
    relay_ticks: int = 3000
    relay_warmup: int = 300
    graph_duration_s: float = 3.0
    sample_time_s: float = 0.001

    def __post_init__(self) -> None:
        if self.rounds < 1:
            raise ConfigError(f"--rounds must be >= 1, got {self.rounds}")


FULL = Plan(rounds=5)
QUICK = Plan(rounds=2, round_trips=300, pingpong_warmup=50, relay_ticks=1000, relay_warmup=100, graph_duration_s=1.0)


@dataclass(frozen=True)
class RoundFigures:
    """One round under one profile: each side's hop in seconds, and the machine's load after it."""

    profile: str
    round: int
    bare_hop_s: float
    relay_hop_s: float
    graph_hop_s: float
    load_average_1min: float

    @property
    def graph_over_bare(self) -> float:
        return self.graph_hop_s / self.bare_hop_s

    @property
    def relay_over_bare(self) -> float:
        return self.relay_hop_s / self.bare_hop_s

    @property
    def graph_over_relay(self) -> float:
        return self.graph_hop_s / self.relay_hop_s


def add_options(parser: argparse.ArgumentParser) -> None:
    """``--rounds`` and ``--dds-profile`` (bench hops)."""
    parser.add_argument("--rounds", type=int, help="rounds of every side (bench hops; default 5, quick 2)")
    parser.add_argument("--dds-profile", action="append", default=[], metavar="NAME=PATH",
                        help="also measure every side under this Fast DDS profile (bench hops; repeatable)")


def parse_profiles(specs: Sequence[str]) -> dict[str, Path]:
    """``NAME=PATH`` options as name -> profile file, the shipped profile first."""
    profiles = {SHIPPED: profile_path()}
    for spec in specs:
        name, sep, path = spec.partition("=")
        if not sep or not name or not path:
            raise ConfigError(f"--dds-profile must be NAME=PATH, got {spec!r}")
        if name in profiles:
            raise ConfigError(f"--dds-profile: the name {name!r} is taken (shipped is the project's own profile)")
        if not Path(path).is_file():
            raise ConfigError(f"--dds-profile {name}: no file {path}")
        profiles[name] = Path(path)
    return profiles


@contextmanager
def dds_profile(path: Path) -> Iterator[None]:
    """Every process started inside the block uses the Fast DDS profile ``path``."""
    saved = {name: os.environ.get(name) for name in PROFILE_VARIABLES}
    os.environ.update({name: str(path) for name in PROFILE_VARIABLES})
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _bare_hop_s(run_dir: Path, plan: Plan) -> float:
    from cnc_tools.bench.peers import round_trips  # the sides' modules: when measured, not on import

    return statistics.median(round_trips(run_dir, "reference", plan.round_trips, plan.pingpong_warmup)) / 2.0


def _relay_hop_s(run_dir: Path, plan: Plan) -> float:
    from cnc_tools.bench.relay import relay_ticks

    return relay_ticks(run_dir, plan.relay_ticks, plan.relay_warmup) / HOPS


def _graph_hop_s(run_dir: Path, plan: Plan) -> float:
    from cnc_tools.runs.graph import run_graph

    summary = run_graph(scenario_at(plan.sample_time_s, plan.graph_duration_s), run_dir).summary
    return float(summary["wall_time_s"]) / int(summary["ticks"]) / HOPS


#: Each side's measurement: run folder and plan in, one hop in seconds out.
SIDES: dict[str, Callable[[Path, Plan], float]] = {"bare": _bare_hop_s, "relay": _relay_hop_s, "graph": _graph_hop_s}


def measure_round(index: int, profile: str, path: Path, run_dir: Path, plan: Plan) -> RoundFigures:
    """Every side once under ``path``, starting with side ``index`` mod 3 (the order rotates by round)."""
    names = tuple(SIDES)
    order = names[index % len(names):] + names[:index % len(names)]
    hops: dict[str, float] = {}
    with dds_profile(path):
        for side in order:
            print(f"  round {index + 1}, {profile}: {side} ...", flush=True)
            hops[side] = SIDES[side](run_dir / f"round{index + 1}_{profile}_{side}", plan)
    return RoundFigures(profile, index + 1, hops["bare"], hops["relay"], hops["graph"], machine()["load_average_1min"])


def summarize(rounds: Sequence[RoundFigures]) -> list[dict[str, Any]]:
    """Per profile: the median, lowest and highest of each ratio over the rounds, and the goal on the median."""
    rows = []
    for profile in dict.fromkeys(r.profile for r in rounds):
        mine = [r for r in rounds if r.profile == profile]
        row: dict[str, Any] = {"profile": profile, "rounds": len(mine)}
        for ratio in ("graph_over_bare", "relay_over_bare", "graph_over_relay"):
            values = [getattr(r, ratio) for r in mine]
            row[ratio] = {"median": statistics.median(values), "min": min(values), "max": max(values)}
        for hop in ("bare_hop_s", "relay_hop_s", "graph_hop_s"):
            row[hop] = statistics.median(getattr(r, hop) for r in mine)
        row["met"] = row["graph_over_bare"]["median"] <= HOP_RATIO_GOAL
        rows.append(row)
    return rows


def hops_bench(options: argparse.Namespace) -> int:
    """Interleaved rounds of the bare hop, the relay graph and the node graph; print the tables, write JSON."""
    base = QUICK if options.quick else FULL
    plan = Plan(**{**asdict(base), "rounds": options.rounds or base.rounds})
    profiles = parse_profiles(getattr(options, "dds_profile", []))
    run_dir = options.out or project_root() / "bags" / "bench" / "hops" / timestamp()
    load_at_start = machine()["load_average_1min"]
    print(f"hops bench ({'quick' if options.quick else 'full'}), {plan.rounds} rounds, profiles "
          f"{', '.join(profiles)}; run files in {run_dir}", flush=True)
    pairs = [(i, name, path) for i in range(plan.rounds) for name, path in profiles.items()]
    rounds = [measure_round(i, name, path, run_dir, plan) for i, name, path in track(pairs, "hops rounds")]
    figures = {"bench": "hops", "quick": options.quick, "plan": asdict(plan), "machine": machine(),
               "profiles": {name: str(path) for name, path in profiles.items()}, "hops_per_tick": HOPS,
               "goal": HOP_RATIO_GOAL, "rounds": [{**asdict(r), "graph_over_bare": r.graph_over_bare,
                                                     "relay_over_bare": r.relay_over_bare,
                                                     "graph_over_relay": r.graph_over_relay} for r in rounds],
               "summary": summarize(rounds)}
    figures["machine"]["load_average_1min_at_start"] = load_at_start
    print_figures(figures)
    write_json(options.json, figures)
    return 0


def print_figures(figures: dict[str, Any]) -> None:
    """The rounds, then the medians per profile."""
    m, plan = figures["machine"], figures["plan"]
    print(f"\nmachine: {m['cpus']} cores, {m['cpu']}, Python {m['python']}, {m['rmw']}; 1-min load average "
          f"{m['load_average_1min_at_start']:.2f} at start, {m['load_average_1min']:.2f} at end")
    print(f"graph at T = {plan['sample_time_s'] * 1e3:g} ms, {figures['hops_per_tick']} hops per tick; relay "
          f"{plan['relay_ticks']} ticks; ping-pong {plan['round_trips']} round trips (Reference)")
    print(format_table(["round", "profile", "bare hop [us]", "relay hop [us]", "graph hop [us]", "relay / bare",
                        "graph / bare", "graph / relay", "load"], [
        [r["round"], r["profile"], r["bare_hop_s"] * 1e6, r["relay_hop_s"] * 1e6, r["graph_hop_s"] * 1e6,
         r["relay_over_bare"], r["graph_over_bare"], r["graph_over_relay"], r["load_average_1min"]]
        for r in figures["rounds"]]))
    print(f"\nmedian over the rounds (lowest-highest); goal: graph / bare <= {figures['goal']:g}")
    print(format_table(["profile", "rounds", "graph / bare", "relay / bare", "graph / relay", "goal"], [
        [s["profile"], s["rounds"], _spread(s["graph_over_bare"]), _spread(s["relay_over_bare"]),
         _spread(s["graph_over_relay"]), goal_text(s["met"])] for s in figures["summary"]]))


def _spread(ratio: dict[str, float]) -> str:
    return f"{ratio['median']:.2f} ({ratio['min']:.2f}-{ratio['max']:.2f})"
