"""Bench ``paper002-speed``: issue 10's speed figures, measured side by side in one run.

1. Per-step cost of each paper-002 law as a ratio to the plain P law: the
   law's ``step`` alone and the whole servo step (the engine's and the node's
   ``ServoController.parts``), the laws interleaved in every repeat (best of
   the repeats), so a change of load hits all of them alike.
2. The PDC's design time when the spindle speed changes: ``set_spindle_rpm``
   (config, L, P_m, W by RLS or with W(1) = 0, the taps swapped) for speeds
   never designed before (the design cache cannot answer), per
   ``spare_dof``; against the budget of one spindle override: well under 1 s.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import time
import timeit
from collections.abc import Callable
from typing import Any

from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.laws import LawSample, make_law
from cnc_contour_control.laws.disturbance import DisturbanceLaw
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.reproductions.paper002 import data
from cnc_tools.reproductions.paper002.runs import KP_PER_S, METHODS, law_params

#: Repeats of the step timing (the best is kept).
REPEATS = 20
#: The design-time budget of one spindle change [s] (issue 10: well under one second).
DESIGN_BUDGET_S = 1.0
#: The spare-DOF readings whose design time is measured.
SPARE_DOFS = ("zero_dc", "rls")
#: The laws timed: key -> (law, parameters beyond ``law_params``): the paper's methods and MBDA+PDC estimating f_d
#: (``track_fd``) with its gate shut (the samples are no plant, and a redesign's cost is the design time below).
TIMED: dict[str, tuple[str, dict[str, Any]]] = {
    **{law: (law, {}) for law in METHODS},
    "MBDA+PDC, f_d estimated": ("mbda_pdc", {"track_fd": True, "track_min_amplitude": 1.0e6})}
#: The paper-002 servo around a law (m, m/s: the scenario's units).
SERVO = {"axis_name": "x", "counts_per_m": 1.0, "output_limit": 1.0, "quantum": 0.0, "command_unit": "m/s"}


def _samples(n: int) -> list[tuple[float, float, float]]:
    """(error [m], velocity [m/s], applied command [m/s]) of a 2 mm/s axis with a 50 Hz ripple."""
    return [(2e-6 * math.sin(0.3 * k), 2e-3 + 1.5e-4 * math.sin(2 * math.pi * 0.05 * k), 2e-3) for k in range(n)]


def _law_runner(key: str, samples: list[tuple[float, float, float]]) -> Callable[[], None]:
    law, extra = TIMED[key]
    step, sample = make_law(law, {**law_params(law), **extra}).step, LawSample(dt_s=1e-3)

    def run() -> None:
        for error, velocity, command in samples:
            sample.error_counts, sample.velocity_counts_s, sample.applied_command = error, velocity, command
            step(sample)
    return run


def _servo_runner(key: str, samples: list[tuple[float, float, float]]) -> Callable[[], None]:
    law, extra = TIMED[key]
    parts = ServoController(ServoConfig.from_mapping({**SERVO, "law": law,
                                                      "law_params": {**law_params(law), **extra}})).parts

    def run() -> None:
        for error, velocity, _ in samples:
            parts(1e-3, error, 2e-3, 0.0, 0.0, velocity, 0.0)
    return run


def step_costs_us(steps: int, repeats: int = REPEATS) -> dict[str, dict[str, float]]:
    """µs per step, {level: {law: best of ``repeats``}} over ``steps`` in all, every law timed in each repeat
    (interleaved: short repeats, many of them, so the best one finds a quiet moment on a loaded machine)."""
    samples = _samples(1000)
    number = max(1, steps // (len(samples) * repeats))
    runners = {level: {key: make(key, samples) for key in TIMED}
               for level, make in (("law step", _law_runner), ("servo step", _servo_runner))}
    best: dict[str, dict[str, float]] = {level: dict.fromkeys(TIMED, math.inf) for level in runners}
    for _ in range(repeats):
        for level, by_law in runners.items():
            for law, run in by_law.items():
                seconds = timeit.timeit(run, number=number) / (number * len(samples))
                best[level][law] = min(best[level][law], seconds * 1e6)
    return best


def design_times_s(changes: int) -> dict[str, list[float]]:
    """Wall time of ``set_spindle_rpm`` per spare-DOF reading for ``changes`` speeds not designed before."""
    times: dict[str, list[float]] = {}
    for spare_dof in SPARE_DOFS:
        law = make_law("pdc", {"kp": KP_PER_S, "spindle_rpm": data.SPINDLE_RPM, "spare_dof": spare_dof})
        assert isinstance(law, DisturbanceLaw)
        times[spare_dof] = []
        for i in range(changes):
            rpm = data.SPINDLE_RPM * (0.9 + 0.2 * (i + 0.5) / changes)  # ±10 %, each new to the cache
            started = time.perf_counter()
            law.set_spindle_rpm(rpm)
            times[spare_dof].append(time.perf_counter() - started)
    return times


def print_costs(costs: dict[str, dict[str, float]]) -> None:
    """µs per step and the ratio to P, per law and level."""
    rows = [[METHODS.get(key, key), *[f"{costs[level][key]:.2f}" for level in costs],
             *[f"{costs[level][key] / costs[level]['p']:.2f}" for level in costs]] for key in TIMED]
    print(format_table(["law", *[f"{level} µs" for level in costs], *[f"{level} / P" for level in costs]], rows))


def print_design(times: dict[str, list[float]]) -> None:
    """Median and worst design time per spare-DOF reading against the budget."""
    rows = [[spare, len(found), f"{1e3 * statistics.median(found):.1f}", f"{1e3 * max(found):.1f}",
             f"< {DESIGN_BUDGET_S:g} s: {goal_text(max(found) < DESIGN_BUDGET_S)}"] for spare, found in times.items()]
    print(format_table(["spare_dof", "changes", "median ms", "max ms", "budget"], rows))


def paper002_speed_bench(options: argparse.Namespace) -> int:
    """The speed figures of issue 10 (see the module docstring)."""
    quick = bool(getattr(options, "quick", False))
    steps, changes = (20_000, 3) if quick else (200_000, 10)
    print(f"paper002-speed: {steps} steps per law and level, interleaved, best of {REPEATS}; {changes} spindle changes "
          f"per spare_dof; 1-min load {os.getloadavg()[0]:.2f}", flush=True)
    costs = step_costs_us(steps)
    print_costs(costs)
    times = design_times_s(changes)
    print("\nPDC design time when the spindle speed changes (set_spindle_rpm: config, L, P_m, W, taps swapped):")
    print_design(times)
    print(f"1-min load after: {os.getloadavg()[0]:.2f}")
    result: dict[str, Any] = {"bench": "paper002-speed", "machine": machine(), "step_us": costs,
                              "design_s": times, "load_1min": os.getloadavg()[0]}
    write_json(getattr(options, "json", None), result)
    return 0
