"""Bench ``laws``: cost per step of each servo law, as a ratio to the PID, measured in one run.

Two levels: the feedback law alone (a sweep of errors) and
the whole servo step a node makes per tick and axis (error scaling,
feedforward, saturation, 8-bit quantisation).
"""
from __future__ import annotations

import argparse
import math
import timeit

from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.laws import LawSample, make_law
from cnc_contour_control.laws.fuzzy_gains import format_gains_table
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json

RATIO_GOAL = 3.0
LAW_PARAMS = {"pid": {"kp": 2.4, "ki": 10.0, "kd": 0.067}, "fuzzy": {}}  # Table 4 at T = 10 ms


def law_step_us(law: str, steps: int) -> float:
    """Microseconds per ``law.step`` alone, best of 5, over a sweep of errors [BLU]."""
    step = make_law(law, LAW_PARAMS[law]).step
    errors = [25.0 * math.sin(0.05 * k) + 0.3 * math.sin(1.7 * k) for k in range(1000)]
    sample = LawSample(dt_s=0.01)

    def run() -> None:
        for e in errors:
            sample.error_counts = e
            step(sample)

    repeats = max(1, steps // len(errors))
    return min(timeit.repeat(run, number=repeats, repeat=5)) / (repeats * len(errors)) * 1e6


def servo_step_us(law: str, steps: int) -> float:
    """Microseconds per ServoController.step with ``law``, best of 5, over a sweep of errors."""
    servo = ServoController(ServoConfig.from_mapping({"axis_name": "x", "law": law, "law_params": LAW_PARAMS[law]}))
    errors_m = [2.5e-4 * math.sin(0.05 * k) + 3e-6 * math.sin(1.7 * k) for k in range(1000)]
    step = servo.step

    def run() -> None:
        for e in errors_m:
            step(0.01, e, 0.01, 0.0, 0.0, 0.01, 0.0)

    repeats = max(1, steps // len(errors_m))
    return min(timeit.repeat(run, number=repeats, repeat=5)) / (repeats * len(errors_m)) * 1e6


def laws(options: argparse.Namespace) -> int:
    """FLC vs PID: µs per step of the law alone and of the whole servo step."""
    steps = 20_000 if options.quick else 200_000
    law_us = {name: law_step_us(name, steps) for name in LAW_PARAMS}
    servo_us = {name: servo_step_us(name, steps) for name in LAW_PARAMS}
    rows = [[level, round(cost["pid"], 3), round(cost["fuzzy"], 3), round(cost["fuzzy"] / cost["pid"], 2),
             f"<= {RATIO_GOAL}: {goal_text(cost['fuzzy'] / cost['pid'] <= RATIO_GOAL)}"]
            for level, cost in (("law step", law_us), ("servo step", servo_us))]
    print(format_table(["level", "PID µs", "FLC µs", "FLC/PID", "goal"], rows))
    print(format_gains_table())
    write_json(options.json, {"bench": "laws", "law_us": law_us, "servo_us": servo_us, "machine": machine()})
    return 0
