"""Bench ``tune``: evaluations per second of the tuner's objectives, and the simulated one's parallel speed-up.

- analytic: :class:`AnalyticObjective` (paper 003 Eq. 17 over the 24-circle grid) at
  random points of K1 <= 100, K2 <= 2.6; and the constraint figures (phase and gain
  margin of the delayed position loop, rise time) at the same points;
- circular: :class:`CircularObjective` (a CW and a CCW engine run of
  ``scenarios/paper000_circle_high.yaml``, diagnosed) at random
  ``servo.law_params.kp``, once in this process and once through a pool of
  :data:`WORKERS` spawned processes, the way ``cnc-contour tune`` evaluates a
  generation (``executor.map``). The pool's workers are started and warmed
  before the timed map (start time printed, not counted).

Figures: evaluations/s, speed-up = wall(1 process) / wall(pool), efficiency =
speed-up / workers, the 1-min load before and after (other agents share the
cores), and whether the pool's values equal the in-process ones.
"""
from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.runs.executor import LocalExecutor
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import load_scenario
from cnc_tools.tuning.objectives import AnalyticObjective, CircularObjective, constraint_values, model_at
from cnc_tools.tuning.problem import Constraint, DesignVariable

SCENARIO = "scenarios/paper000_circle_high.yaml"
WORKERS = 2
ANALYTIC_VARIABLES = (DesignVariable("plant.axis_overrides.*.ki", 10.0, 100.0),
                      DesignVariable("plant.axis_overrides.*.kp", 0.1, 2.6))
CONSTRAINTS = (Constraint("phase_margin_deg", ">=", 45.0), Constraint("gain_margin_db", ">=", 6.0),
               Constraint("rise_time_s", "<=", 0.2))


def _points(variables: Sequence[DesignVariable], count: int, seed: int = 7) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    low, high = np.array([v.low for v in variables]), np.array([v.high for v in variables])
    return [low + (high - low) * rng.random(len(variables)) for _ in range(count)]


def _rate(fn: Callable[[np.ndarray], Any], points: list[np.ndarray]) -> tuple[float, list[Any]]:
    """(evaluations/s, values) of ``fn`` over ``points`` in this process."""
    start = time.perf_counter()
    values = [fn(x) for x in points]
    return len(points) / (time.perf_counter() - start), values


def _pool_rate(objective: CircularObjective, points: list[np.ndarray]) -> tuple[float, float, list[float]]:
    """(evaluations/s, start s, values) through a warmed pool of WORKERS processes."""
    with LocalExecutor(WORKERS) as executor:
        start = time.perf_counter()
        executor.map(objective, points[:WORKERS])
        warm_s = time.perf_counter() - start
        start = time.perf_counter()
        values = executor.map(objective, points)
        return len(points) / (time.perf_counter() - start), warm_s, values


def tune_bench(options: argparse.Namespace) -> int:
    """Measure and print the figures (and write them as JSON when asked); 1 if pool and process differ."""
    quick = bool(getattr(options, "quick", False))
    n_analytic, n_circular = (20, 6) if quick else (100, 16)
    load_before = os.getloadavg()[0]
    analytic = AnalyticObjective({}, ANALYTIC_VARIABLES)
    analytic_rate, _ = _rate(analytic, _points(ANALYTIC_VARIABLES, n_analytic))
    constraint_rate, _ = _rate(lambda x: constraint_values(model_at({}, ANALYTIC_VARIABLES, x), CONSTRAINTS),
                               _points(ANALYTIC_VARIABLES, n_analytic))
    scenario = load_scenario(project_root() / SCENARIO)
    circular = CircularObjective(scenario, (DesignVariable("servo.law_params.kp", 1.0, 4.0),))
    points = _points(circular.variables, n_circular)
    one_rate, one_values = _rate(circular, points)
    pool_rate, warm_s, pool_values = _pool_rate(circular, points)
    same = bool(np.array_equal(one_values, pool_values))
    speed_up = pool_rate / one_rate
    rows = [["analytic objective (24 circles)", n_analytic, analytic_rate, "-", "-"],
            ["constraints (PM, GM, rise)", n_analytic, constraint_rate, "-", "-"],
            ["circular objective, 1 process", n_circular, one_rate, 1.0, 1.0],
            [f"circular objective, pool of {WORKERS}", n_circular, pool_rate, speed_up, speed_up / WORKERS]]
    print(format_table(["what", "evaluations", "evaluations/s", "speed-up", "efficiency"], rows))
    print(f"pool start + warm-up {warm_s:.2f} s (not counted); pool values equal in-process ones: {same}")
    print(f"1-min load {load_before:.2f} before, {os.getloadavg()[0]:.2f} after, on {os.cpu_count()} cores "
          "(a speed-up below the worker count on a shared machine is the load, not the method)")
    if getattr(options, "json", None):
        write_json(Path(options.json), {"bench": "tune", "machine": machine(), "analytic_per_s": analytic_rate,
                                        "constraints_per_s": constraint_rate, "circular_per_s": one_rate,
                                        "circular_pool_per_s": pool_rate, "speed_up": speed_up, "workers": WORKERS,
                                        "same_values": same, "load_before": load_before})
    return 0 if same else 1
