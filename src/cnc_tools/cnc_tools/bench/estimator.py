"""Bench ``estimator``: the contour-error estimators against the scorer's exact error, and their cost per step.

Fidelity (:mod:`cnc_tools.reproductions.paper001.fidelity`): five contours
run closed-loop in the engine at T = 1 ms; every estimator of the registry is
stepped over the recorded (reference, position) pairs and compared with the
exact signed contour error: max and RMS |estimate − exact| [µm] on the
samples where the axes follow the reference, the worst case and where
(time, path position, distance to the nearest junction), the worst case
where the axes run ahead of the reference, and window steps per sample in
steady state.

Cost: each estimator's ``step`` over the circle run's recorded pairs and
:meth:`ServoController.parts` (the engine's per-tick servo call) over the
same ticks, in one process, alternated, best of several passes; the ratio
estimator/servo is what the issue asks for (per-step cost as a ratio to
the servo's step).
"""
from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Callable, Sequence
from typing import Any

from cnc_contour_control.axis.servo import ServoController
from cnc_contour_control.estimators import ESTIMATORS, make_estimator
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.reproductions.paper001.fidelity import (
    CONTOURS,
    GOAL_MAX_UM,
    GOAL_RMS_UM,
    GOAL_STEPS,
    FidelityRow,
    get_contour,
    measure,
    run_contour,
)
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.folders import project_root

#: The run whose ticks the cost is measured on.
COST_CONTOUR = "circle"


def _best_pass_us(run_pass: Callable[[], None], ticks: int) -> float:
    started = time.perf_counter()
    run_pass()
    return (time.perf_counter() - started) / ticks * 1e6


def step_costs_us(record: RunRecord, servo: ServoController, names: Sequence[str], repeats: int) -> dict[str, float]:
    """µs per step of each estimator and of the servo (key ``"servo"``) over ``record``'s ticks, best of ``repeats``."""
    reference, position = record.reference.position_m.tolist(), record.joint_states.position_m.tolist()  # type: ignore[union-attr]  # engine runs have both
    passes: dict[str, Callable[[], None]] = {name: _estimator_pass(make_estimator(name, {}, record.program),
                                                                   reference, position) for name in names}
    passes["servo"] = _servo_pass(servo, record)
    best = {name: float("inf") for name in passes}
    for _ in range(repeats):
        for name, run_pass in passes.items():  # alternated, so a change of machine load hits every one
            best[name] = min(best[name], _best_pass_us(run_pass, len(reference)))
    return best


def _estimator_pass(estimator: Any, reference: list[list[float]], position: list[list[float]]) -> Callable[[], None]:
    step = estimator.step

    def run_pass() -> None:
        estimator.reset()
        for ref, pos in zip(reference, position):
            step(ref, pos)
    return run_pass


def _servo_pass(servo: ServoController, record: RunRecord) -> Callable[[], None]:
    """The x axis's servo over the run's ticks, as the engine's servo stage calls it."""
    reference = record.reference
    assert reference is not None
    rows = list(zip(reference.position_m[:, 0].tolist(), reference.velocity_m_s[:, 0].tolist(),
                    reference.acceleration_m_s2[:, 0].tolist(), record.joint_states.position_m[:, 0].tolist(),
                    record.joint_states.velocity_m_s[:, 0].tolist()))
    dt_s, parts = float(record.joint_states.stamp_ns[1] - record.joint_states.stamp_ns[0]) * 1e-9, servo.parts

    def run_pass() -> None:
        servo.reset()
        for ref, ref_v, ref_a, pos, vel in rows:
            parts(dt_s, ref, ref_v, ref_a, pos, vel, 0.0)
    return run_pass


def _goal(row: FidelityRow) -> str:
    met = row.goals_met
    return "corners: reported" if met is None else goal_text(met)


def fidelity_table(rows: Sequence[FidelityRow]) -> str:
    """Accuracy on the samples following the reference (µm; where: s, mm) and the goal verdict."""
    header = ["contour", "estimator", "n", "max|ε| µm", "max|Δ| µm", "RMS Δ µm", "max||Δ|| µm", "worst at t s",
              "s mm", "junction mm", "goal"]
    body = [[r.contour, r.estimator, r.samples, round(r.contour_max_um, 1), _um(r.max_um), _um(r.rms_um),
             _um(r.magnitude_max_um), round(r.worst.time_s, 3), round(r.worst.path_mm, 3), _mm(r.worst.junction_mm),
             _goal(r)] for r in rows]
    return format_table(header, body)


def steps_table(rows: Sequence[FidelityRow]) -> str:
    """Window steps and distances per sample in steady state, and the worst case ahead of the reference."""
    header = ["contour", "estimator", "steady n", "steps mean", "steps max", "window mean", "window max",
              "ahead n", "ahead max|Δ| µm", "at t s", "s mm"]
    body = [[r.contour, r.estimator, r.steady_samples, round(r.steps_mean, 2), r.steps_max, round(r.window_mean, 2),
             r.window_max, r.ahead_samples, _um(r.ahead.error_um), round(r.ahead.time_s, 3), round(r.ahead.path_mm, 3)]
            for r in rows]
    return format_table(header, body)


def _um(value: float) -> str:
    return f"{value:.4f}" if value < 10 else f"{value:.1f}"


def _mm(value: float) -> str:
    return "-" if value == float("inf") else f"{value:.3f}"


def cost_table(costs: dict[str, float]) -> str:
    """µs per step and the ratio to the servo's step."""
    servo = costs["servo"]
    rows = [[name, round(us, 2), round(us / servo, 2)] for name, us in costs.items()]
    return format_table(["step", "µs per step (best pass)", "ratio to ServoController.parts"], rows)


def estimator_bench(options: argparse.Namespace) -> int:
    """Fidelity of every estimator on the five contours, then the step costs as ratios to the servo's."""
    root, names = project_root(), sorted(ESTIMATORS)
    load = machine()["load_average_1min"]
    rows: list[FidelityRow] = []
    records: dict[str, RunRecord] = {}
    for contour in CONTOURS:
        print(f"  {contour.name}: {contour.note} ...", flush=True)
        records[contour.name] = run_contour(contour, root)
        rows += measure(contour, records[contour.name], names)
    print("  Δ = estimate − exact (signed); ||Δ|| = |estimate| − |exact|; n: samples following the reference; "
          "ahead: samples at or past the newest reference")
    print(fidelity_table(rows))
    print(steps_table(rows))
    print(f"  goals on smooth contours, samples following the reference: max|Δ| <= {GOAL_MAX_UM} µm, "
          f"RMS <= {GOAL_RMS_UM} µm, window steps <= {GOAL_STEPS} per sample in steady state")
    servo = ServoController(get_contour(COST_CONTOUR).load(root).servos[0])
    costs = step_costs_us(records[COST_CONTOUR], servo, names, repeats=3 if options.quick else 9)
    print(cost_table(costs))
    print(f"  cost over the {COST_CONTOUR} run's {records[COST_CONTOUR].ticks} ticks; load {load} (1 min) at start")
    write_json(options.json, {"bench": "estimator", "rows": [dataclasses.asdict(r) for r in rows],
                              "step_us": costs, "ratio_to_servo": {k: v / costs["servo"] for k, v in costs.items()},
                              "goals": {"max_um": GOAL_MAX_UM, "rms_um": GOAL_RMS_UM, "steps": GOAL_STEPS},
                              "machine": machine()})
    return 0
