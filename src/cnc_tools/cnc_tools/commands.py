"""Subcommands of ``cnc-contour`` (each registers itself in :data:`cnc_tools.cli.COMMANDS`)."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from cnc_tools.cli import command, parse_overrides, project_root, timestamp
from cnc_tools.engine import run_engine
from cnc_tools.runner import run_graph
from cnc_tools.scenario import load_scenario


def _configure_run(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=Path, help="scenario YAML file")
    parser.add_argument("--engine", action="store_true", help="run in-process (no DDS) instead of the node graph")
    parser.add_argument("--out", type=Path, help="run folder (default bags/<scenario>/<timestamp>)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario key, e.g. --set servo.law_params.kp=3 --set mode=realtime")


@command("run", _configure_run)
def run(args: argparse.Namespace) -> int:
    """Run a scenario through the node graph (or the engine) and print its summary."""
    scenario = load_scenario(args.scenario, parse_overrides(args.overrides))
    if args.engine:
        result = run_engine(scenario)
        summary = {"ticks": result.ticks, "simulated_time_s": float(result.time_s[-1]),
                   "wall_time_s": result.wall_time_s, "real_time_factor": result.real_time_factor, "faults": []}
        print_summary(scenario.name, "engine", summary)
        return 0
    run_dir = args.out or project_root() / "bags" / scenario.name / timestamp()
    print(f"running {scenario.name} through the node graph ({scenario.mode}, T = {scenario.sample_time_s} s, "
          f"{scenario.duration_s:.2f} s simulated) in {run_dir}", flush=True)
    result = run_graph(scenario, run_dir)
    print_summary(scenario.name, "node graph", result.summary)
    return 1 if result.faults else 0


def print_summary(name: str, how: str, summary: dict[str, object]) -> None:
    """The run summary as an aligned table."""
    rows = [("scenario", name), ("ran on", how), ("ticks", summary["ticks"]),
            ("simulated time [s]", f"{summary['simulated_time_s']:.3f}"),
            ("wall time [s]", f"{summary['wall_time_s']:.3f}"),
            ("real-time factor", f"{summary['real_time_factor']:.3f}")]
    if "late_commands" in summary:
        rows.append(("late commands", summary["late_commands"]))
    faults = summary.get("faults") or []
    rows.append(("faults", "; ".join(map(str, faults)) if faults else "none"))
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"  {key:<{width}}  {value}")


def _configure_show(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=Path)


@command("check", _configure_show)
def check(args: argparse.Namespace) -> int:
    """Validate a scenario and print what it resolves to."""
    scenario = load_scenario(args.scenario)
    print(json.dumps({"name": scenario.name, "axes": scenario.axes, "sample_time_s": scenario.sample_time_s,
                      "duration_s": scenario.duration_s, "segments": len(scenario.program.segments),
                      "length_mm": scenario.program.total_length_m * 1e3}, indent=2))
    return 0
from cnc_tools.bench import command as _bench_command  # noqa: F401,E402
