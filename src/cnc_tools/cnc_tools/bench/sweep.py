"""Bench ``sweep``: N independent engine runs in one process, in a local pool, and on a loopback Dask cluster.

The runs are seeds of ``scenarios/paper001_circle_neural.yaml`` (the neural
compensator stack, T = 1 ms); each returns its peak following error, which
must be the same in all three configurations. Per configuration a warm-up map
starts the workers (their start is printed, not counted), then the timed map.
The Dask cluster is a ``LocalCluster`` with one single-threaded worker
process per core used, bound to 127.0.0.1 only (the address is checked), and
closed on every way out. Figures: wall time, speed-up over one process,
parallel efficiency, and the 1-min load.
"""
from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import CncError
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.executor import DaskExecutor, Executor, LocalExecutor
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.progress import track
from cnc_tools.runs.scenario import Scenario, load_scenario

SCENARIO = "scenarios/paper001_circle_neural.yaml"
WORKERS = 2


def peak_following_error_m(scenario: Scenario) -> float:
    """One engine run: the largest |following error| of the first axis [m] (module level: workers import it)."""
    record = run_engine(scenario)
    return float(abs(record.commands[scenario.axes[0]].error_m).max())


def worker_ready(value: float) -> float:
    """The warm-up task: unpickling it imports this module, so the engine, in the worker."""
    return value


def _timed(executor: Executor, items: list[Scenario]) -> tuple[float, float, list[Any]]:
    """(warm-up s, timed map s, results): the warm-up starts the workers and imports the engine there."""
    start = time.perf_counter()
    executor.map(worker_ready, [1.0] * WORKERS)
    warm_s = time.perf_counter() - start
    start = time.perf_counter()
    results = executor.map(peak_following_error_m, items)
    return warm_s, time.perf_counter() - start, results


def _dask(items: list[Scenario]) -> tuple[float, float, list[Any]]:
    """The timed map on a loopback ``LocalCluster`` (its start counted as warm-up)."""
    from distributed import LocalCluster

    start = time.perf_counter()
    cluster = LocalCluster(n_workers=WORKERS, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", scheduler_port=0)
    try:
        if not cluster.scheduler_address.startswith("tcp://127.0.0.1:"):
            raise CncError(f"bench sweep: the Dask scheduler is not on loopback: {cluster.scheduler_address}")
        up_s = time.perf_counter() - start
        with DaskExecutor(cluster.scheduler_address) as executor:
            warm_s, wall_s, results = _timed(executor, items)
        return up_s + warm_s, wall_s, results
    finally:
        cluster.close()


def sweep_bench(options: argparse.Namespace) -> int:
    """Run the bench and print (and optionally write) the figures; 1 if a configuration's results differ."""
    quick = bool(getattr(options, "quick", False))
    runs, duration_s = (4, 1.0) if quick else (8, 8.0)
    base = load_scenario(project_root() / SCENARIO)
    # No state file: the runs are independent (and must not write one file at once).
    items = [base.variant({"compensator": {"state_out": ""}}, duration_s=duration_s, seed=seed)
             for seed in range(1, runs + 1)]
    load_before = os.getloadavg()[0]
    configurations: dict[str, Callable[[], tuple[float, float, list[Any]]]] = {
        "1 process": lambda: _in(LocalExecutor(1), items),
        f"pool, {WORKERS} workers": lambda: _in(LocalExecutor(WORKERS), items),
        f"Dask LocalCluster, {WORKERS} workers": lambda: _dask(items)}
    figures: dict[str, dict[str, Any]] = {}
    for name, measure in track(configurations.items(), "sweep configurations"):
        print(f"  {name} ...", flush=True)
        warm_s, wall_s, results = measure()
        figures[name] = {"wall_s": wall_s, "start_s": warm_s, "results": results}
    return _report(options, figures, runs, duration_s, load_before)


def _in(executor: Executor, items: list[Scenario]) -> tuple[float, float, list[Any]]:
    with executor:
        return _timed(executor, items)


def _report(options: argparse.Namespace, figures: dict[str, dict[str, Any]], runs: int, duration_s: float,
            load_before: float) -> int:
    one = figures["1 process"]
    rows, same = [], True
    for name, f in figures.items():
        speed_up = one["wall_s"] / f["wall_s"]
        workers = 1 if name == "1 process" else WORKERS
        same = same and f["results"] == one["results"]
        rows.append([name, round(f["wall_s"], 2), round(speed_up, 2), round(speed_up / workers, 2),
                     round(f["start_s"], 2), str(f["results"] == one["results"])])
    print(f"{runs} runs of {SCENARIO}, {duration_s} s each at T = 1 ms")
    print(format_table(["configuration", "wall s", "speed-up", "efficiency", "start s (not counted)", "same results"],
                       rows))
    print(f"1-min load {load_before:.2f} before, {os.getloadavg()[0]:.2f} after, on {os.cpu_count()} cores")
    if getattr(options, "json", None):
        write_json(Path(options.json), {"bench": "sweep", "runs": runs, "duration_s": duration_s,
                                        "machine": machine(), "figures": figures})
    return 0 if same else 1
