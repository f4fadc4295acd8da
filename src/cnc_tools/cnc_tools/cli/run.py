"""``cnc-contour run SCENARIO``: a scenario through the node graph (or the engine), recorded, scored, plotted."""
from __future__ import annotations

import argparse
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import CncError
from cnc_tools.cli.common import parse_overrides
from cnc_tools.live.options import add_live_arguments, engine_live, graph_live
from cnc_tools.runs.backends import run_on_engine
from cnc_tools.runs.compose import COMPOSE_MODES
from cnc_tools.runs.engine import EngineFault
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.graph import run_graph
from cnc_tools.runs.namespaces import run_namespace
from cnc_tools.runs.outputs import ScoredRun, report_runs, score_bag, score_record
from cnc_tools.runs.scenario import Scenario, load_scenario


def configure(parser: argparse.ArgumentParser) -> None:
    """Options of ``cnc-contour run``."""
    parser.add_argument("scenario", type=Path, help="scenario YAML file")
    parser.add_argument("--engine", action="store_true", help="run in-process (no DDS) instead of the node graph")
    parser.add_argument("--out", type=Path, help="run folder (default bags/<scenario>/<timestamp>)")
    parser.add_argument("--namespace", help="ROS namespace of the run's topics, /clock and /diagnostics included "
                        "(default /cnc/run_<random id>: runs in one ROS domain never meet)")
    parser.add_argument("--compose", choices=sorted(COMPOSE_MODES), default="none",
                        help="nodes in one process on one executor: loop (plant, interpolator, servos and the "
                        "optional stages; the recorder apart), all (the recorder too), "
                        "none (one process each; default)")
    parser.add_argument("--managed", action="store_true",
                        help="start the interpolator, servos and plant unconfigured and let a lifecycle manager "
                        "configure and activate them (default: they autostart)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario key, e.g. --set servo.law_params.kp=3 --set mode=realtime")
    add_live_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Run a scenario through the node graph (or the engine), record it, score it, plot it."""
    scenario = load_scenario(args.scenario, parse_overrides(args.overrides))
    run_dir = args.out or project_root() / "bags" / scenario.name / timestamp()
    if run_dir.exists():
        raise CncError(f"run folder {run_dir} exists already; runs are never overwritten")
    if args.engine:
        print(f"running {scenario.name} in-process (engine, T = {scenario.sample_time_s} s, "
              f"{scenario.duration_s:.2f} s simulated) into {run_dir}", flush=True)
        try:
            with engine_live(args, scenario) as live:
                record = run_on_engine(scenario, run_dir, **live)
        except EngineFault as fault:  # the folder holds every tick before the fault: scored, verdict faulted
            record = fault.record
        print_summary(scenario.name, "engine", record.summary)
        return _outputs(score_record(record, run_dir, force_reference_n=_force_reference_n(scenario)), run_dir,
                        run_dir / "bag")
    namespace = run_namespace(namespace=args.namespace)
    print(f"running {scenario.name} through the node graph ({scenario.mode}, T = {scenario.sample_time_s} s, "
          f"{scenario.duration_s:.2f} s simulated, compose {args.compose}) in namespace {namespace}, "
          f"recording to {run_dir / 'bag'}", flush=True)
    with graph_live(args, namespace, scenario) as live:
        result = run_graph(scenario, run_dir, record=True, on_poll=Progress(run_dir / "summary.json",
                                                                            scenario.duration_s),
                           namespace=namespace, compose=args.compose, managed=args.managed,
                           extra_subscribers=live.extra_subscribers)
    print_summary(scenario.name, "node graph", result.summary)
    if result.faults or result.bag_path is None:
        return 1
    return _outputs(score_bag(result.bag_path, run_dir, force_reference_n=_force_reference_n(scenario)), run_dir,
                    result.bag_path)


def _force_reference_n(scenario: Scenario) -> float | None:
    """The force regulator's reference [N] the run is scored against (None without a regulator)."""
    return None if scenario.force_regulator is None else scenario.force_regulator.setpoint.reference_n


def _outputs(scored: ScoredRun, run_dir: Path, bag: Path | None) -> int:
    """Print the score, draw the plots, list the files of the run folder."""
    print(scored.score.to_table())
    plots = report_runs([scored], run_dir / "report")
    if bag is not None:
        print(f"bag:   {bag}")
    print(f"json:  {scored.json_path}\ncsv:   {scored.csv_path}")
    print("plots: " + "\n       ".join(str(p) for p in plots))
    return 0 if scored.verdict.complete else 1  # the table's verdict line says why


class Progress:
    """Prints the simulated time reached, read from the plant's running summary, at most once a second."""

    def __init__(self, summary_file: Path, duration_s: float) -> None:
        self.summary_file, self.duration_s = summary_file, duration_s
        self.last_print_s = 0.0

    def __call__(self) -> None:
        import time

        now = time.monotonic()
        if now - self.last_print_s < 1.0 or not self.summary_file.exists():
            return
        self.last_print_s = now
        try:
            reached = float(json.loads(self.summary_file.read_text()).get("simulated_time_s", 0.0))
        except (ValueError, OSError):
            return
        print(f"  ... {reached:6.2f} / {self.duration_s:.2f} s simulated ({100 * reached / self.duration_s:3.0f} %)",
              flush=True)


def print_summary(name: str, how: str, summary: Mapping[str, Any]) -> None:
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
