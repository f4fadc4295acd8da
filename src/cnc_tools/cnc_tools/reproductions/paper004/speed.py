"""Bench ``paper004-speed``: issue 12's speed figures, measured side by side in one run.

1. Per-step cost of the force regulator (each law of ``FORCE_LAWS`` with the
   4-bit switch, updating every sample, as the turning scenario runs it:
   ``ForceRegulator.step``) as a ratio to the servo's per-axis step
   (``ServoController.parts`` of the turning scenario's P loop and of paper
   000's PID), all interleaved in every repeat, best of the repeats.
2. The force loop in the node graph at the paper's T = 10 ms: the turning
   scenario run in the engine and in the graph (six nodes), alternating round
   by round; the real-time factor of each run (simulated / wall time, the
   run's summary) beside each other, medians and their ratio.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import tempfile
import timeit
from collections.abc import Callable
from pathlib import Path

from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.core.errors import CncError
from cnc_contour_control.force import FORCE_LAWS
from cnc_contour_control.force.settings import ForceRegulatorSettings
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import Scenario, load_scenario

TURNING = "scenarios/paper004_turning.yaml"
PID = "scenarios/paper000_circle_high.yaml"
#: Samples per timed call (the SMC as the turning scenario runs it; the other laws with their defaults).
SAMPLES = 1000


def _forces_n() -> list[float]:
    """A force trace around 500 N with a step and a ripple (N), the regulator's input."""
    return [500.0 + (150.0 if k > SAMPLES // 2 else 0.0) + 20.0 * math.sin(0.3 * k) for k in range(SAMPLES)]


def _regulator_runner(scenario: Scenario, law: str) -> Callable[[], None]:
    assert scenario.force_regulator is not None
    section = {**scenario.raw["force_regulator"], "law": law}
    if law != scenario.force_regulator.regulator.law:
        section.pop("law_params", None)
    settings = ForceRegulatorSettings.from_mapping(section)
    step, reference_n, forces = settings.make().step, settings.setpoint.reference_n, _forces_n()

    def run() -> None:
        for force in forces:
            step(0.01, force, reference_n)
    return run


def _servo_runner(config: ServoConfig) -> Callable[[], None]:
    parts = ServoController(config).parts
    errors = [1e-5 * math.sin(0.3 * k) for k in range(SAMPLES)]

    def run() -> None:
        for error in errors:
            parts(0.01, error, 2e-3, 0.0, 0.0, 2e-3, 0.0)
    return run


def runners() -> dict[str, Callable[[], None]]:
    """What is timed: the regulator per law and the two servos, by label."""
    turning = load_scenario(project_root() / TURNING)
    pid = load_scenario(project_root() / PID)
    timed = {f"regulator {law}, 4-bit": _regulator_runner(turning, law) for law in FORCE_LAWS}
    timed["servo P (turning)"] = _servo_runner(turning.servos[0])
    timed["servo PID (paper 000)"] = _servo_runner(pid.servos[0])
    return timed


def step_costs_us(steps: int, repeats: int = 5) -> dict[str, float]:
    """µs per step by label, best of ``repeats``, every runner timed in each repeat (interleaved)."""
    timed = runners()
    number = max(1, steps // SAMPLES)
    best = dict.fromkeys(timed, math.inf)
    for _ in range(repeats):
        for label, run in timed.items():
            best[label] = min(best[label], timeit.timeit(run, number=number) / (number * SAMPLES) * 1e6)
    return best


def real_time_factors(rounds: int, duration_s: float) -> tuple[dict[str, list[float]], dict[str, int]]:
    """The turning scenario at T = 10 ms, engine and graph alternating: real-time factor of each run, and the
    number of runs per backend that failed."""
    scenario = load_scenario(project_root() / TURNING, {"duration_s": duration_s})
    factors: dict[str, list[float]] = {"engine": [], "graph": []}
    failed = dict.fromkeys(factors, 0)
    with tempfile.TemporaryDirectory(prefix="cnc_bench_paper004_") as tmp:
        for index in range(rounds):
            for backend in ("engine", "graph") if index % 2 == 0 else ("graph", "engine"):
                print(f"  round {index + 1}/{rounds}: {backend} ...", flush=True)
                try:
                    run = run_scenario(scenario, backend, Path(tmp) / f"{backend}{index}")
                except CncError as err:   # a graph run that fails under load is counted, not hidden
                    print(f"    {backend} run failed: {err}")
                    failed[backend] += 1
                    continue
                factors[backend].append(float(run.summary["real_time_factor"]))
    return factors, failed


def print_costs(costs: dict[str, float]) -> None:
    """µs per step and the ratio to each servo."""
    servos = [label for label in costs if label.startswith("servo")]
    rows = [[label, f"{us:.2f}", *[f"{us / costs[s]:.2f}" for s in servos]] for label, us in costs.items()]
    print(format_table(["step", "µs", *[f"/ {s}" for s in servos]], rows))


def print_factors(factors: dict[str, list[float]], failed: dict[str, int], duration_s: float) -> None:
    """Median, min and max real-time factor per backend (and failed runs), the ratio of the medians."""
    rows = [[backend, len(found), failed[backend], *(f"{f(found):.2f}" if found else "-"
                                                      for f in (statistics.median, min, max))]
            for backend, found in factors.items()]
    print(format_table(["backend", "runs", "failed", "RTF median", "min", "max"], rows))
    if all(factors.values()):
        ratio = statistics.median(factors["graph"]) / statistics.median(factors["engine"])
        print(f"graph / engine real-time factor: {ratio:.4f} ({TURNING}, {duration_s:g} s, T = 10 ms)")


def paper004_speed_bench(options: argparse.Namespace) -> int:
    """The speed figures of issue 12 (see the module docstring)."""
    quick = bool(getattr(options, "quick", False))
    steps, rounds, duration_s = (10_000, 2, 3.0) if quick else (100_000, 4, 12.0)
    print(f"paper004-speed: {steps} steps per row, interleaved, best of 5; then {rounds} rounds engine/graph of "
          f"{TURNING} ({duration_s:g} s); 1-min load {os.getloadavg()[0]:.2f}", flush=True)
    costs = step_costs_us(steps)
    print_costs(costs)
    factors, failed = real_time_factors(rounds, duration_s)
    print_factors(factors, failed, duration_s)
    print(f"1-min load after: {os.getloadavg()[0]:.2f}")
    write_json(getattr(options, "json", None), {
        "bench": "paper004-speed", "machine": machine(), "step_us": costs, "real_time_factor": factors,
        "failed_runs": failed, "duration_s": duration_s, "load_1min": os.getloadavg()[0]})
    return 0
