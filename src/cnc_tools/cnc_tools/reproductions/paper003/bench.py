"""Bench ``paper003``: Table 2 and the two results beside ours, simulated on the paper-003 plant, and the goals.

Printed, the paper's number beside ours in every table:

(a) Table 2 (ζ, ω_n, K1, K2 standard / optimal) with ours computed from K1, K2
    (K_t/J_m = 157), and the analytic readings of the open points
    (:mod:`cnc_tools.tuning.paper003_readings`: radius, loop, rise time);
(b) rise time to 1000 mm/min (paper 0.16 -> 0.13 s), simulated on the loop and
    analytic, at our k = 30 /s and at the k fitted so the standard column rises in 0.16 s;
(c) the radius reduction over the grid (per test, then max and mean), standard
    and optimal columns at k = 30 /s, simulated through the executor, with the
    linear prediction beside each test, and the k at which the predicted mean is 135 µm;
(d) goal (1): the tuned setting (K1, K2, k, ff1) beside both columns over the grid;
(e) goal (2): the analytic optimum per reading and box beside the paper's optimum;
and the speed: grid runs per second in one process and through the executor.

``--quick``: a reduced grid (F 4000/8000, R 1.5/3/10, CW and CCW), one circle
and 3 generations for goal (1), 5 generations for goal (2).
``--workers N`` / ``--scheduler tcp://host:port``: the executor of the grid
and of goal (1)'s generations (default: all cores).
"""
from __future__ import annotations

import argparse
import os
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.reproductions.paper003 import data
from cnc_tools.reproductions.paper003.goals import (
    SearchPlan,
    analytic_optima,
    gain_for_mean_um,
    margins_of,
    predicted_mean_um,
    tune_on_grid,
)
from cnc_tools.reproductions.paper003.runs import (
    CircleMeasure,
    GridCircle,
    Setting,
    column_setting,
    grid,
    grid_measures,
    measure_rise_time_s,
    model_of_scenario,
    predicted_reduction_um,
    rise_scenario,
    summary_um,
)
from cnc_tools.runs.executor import LocalExecutor, make_executor
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import Scenario, load_scenario
from cnc_tools.tuning import paper003_model as p3
from cnc_tools.tuning.paper003_readings import loop_rows, radius_rows, rise_rows
from cnc_tools.tuning.solve import TuningResult

SCENARIO = "scenarios/paper003_circle.yaml"
#: Our position gain for the paper's columns [1/s] (the scenario's; the paper gives none).
OUR_GAIN_1_S = 30.0


@dataclass(frozen=True)
class Plan:
    """What the bench runs: the grid, goal (1)'s circles and search, goal (2)'s generations."""

    quick: bool
    circles: tuple[GridCircle, ...]
    tune_circles: tuple[GridCircle, ...]
    search: SearchPlan
    analytic_maxiter: int


def make_plan(quick: bool) -> Plan:
    """The full plan, or the reduced one of ``--quick``."""
    if quick:
        return Plan(True, grid((4000.0, 8000.0), (1.5, 3.0, 10.0)), (GridCircle(4000.0, 10.0, "cw"),),
                    SearchPlan(maxiter=3, popsize=2), 5)
    return Plan(False, grid(), grid((4000.0, 8000.0), data.GRID_RADII_MM, ("cw",)), SearchPlan(8, 5), 40)


def _round(value: Any, digits: int = 4) -> Any:
    return "-" if value is None else (round(value, digits) if isinstance(value, float) else value)


def table2_text() -> str:
    """(a) Table 2 beside ours: ζ and ω_n computed from the paper's K1, K2 with K_t/J_m = 157."""
    rows = []
    for column in data.COLUMNS:
        paper = data.PAPER003_TABLE[column]
        ours = p3.model_of_column(column)
        rows.append([column, f"{paper.zeta:g}", f"{ours.zeta:.3f}", f"{paper.omega_n_rad_s:g}",
                     f"{ours.omega_n_rad_s:.1f}", f"{paper.k1:g}", f"{paper.k2:g}"])
    return format_table(["column", "zeta paper", "zeta ours", "omega_n paper", "omega_n ours", "K1 (both)",
                         "K2 (both)"], rows)


def readings_text() -> str:
    """(a) the analytic readings of 135 -> 90 µm and 0.16 -> 0.13 s (tuning/paper003_readings)."""
    radius_keys = ("lag", "form", "std_um", "opt_um", "ratio", "t_ip_fit_s", "std_fit_um", "opt_fit_um")
    loop_keys = ("position_gain_1_s", "std_um", "opt_um", "ratio")
    return "\n".join([
        f"  analytic readings, mean over the grid [um] (paper {data.PAPER003_TABLE['standard'].radius_error_um:g} -> "
        f"{data.PAPER003_TABLE['optimal'].radius_error_um:g}, ratio {data.paper_ratio('radius_error_um'):.3f})",
        format_table(radius_keys, [[_round(r[k]) for k in radius_keys] for r in radius_rows()]),
        "  the continuous position loop's radius loss R(1 - |T(jw)|), mean over the grid [um]",
        format_table(loop_keys, [[_round(r[k]) for k in loop_keys] for r in loop_rows()])])


def rise_text(base: Scenario) -> tuple[str, list[dict[str, Any]]]:
    """(b) rise time to 1000 mm/min, simulated and analytic, at our k and at k fitted to 0.16 s (analytic)."""
    fitted = next(r["position_gain_1_s"] for r in rise_rows() if r["position_gain_1_s"] is not None)
    rows: list[dict[str, Any]] = []
    for gain in (OUR_GAIN_1_S, fitted):
        for column in data.COLUMNS:
            setting = column_setting(column, gain)
            rows.append({"k_1_s": gain, "column": column, "paper_s": data.PAPER003_TABLE[column].rise_time_s,
                         "simulated_s": measure_rise_time_s(rise_scenario(base, setting)),
                         "analytic_s": p3.rise_time_position_loop_s(setting.model(model_of_scenario(base)))})
    keys = ("k_1_s", "column", "paper_s", "simulated_s", "analytic_s")
    text = format_table(keys, [[_round(r[k]) for k in keys] for r in rows])
    return text + "\n  velocity loop alone (Eq. 1, 10-90 %): " + ", ".join(
        f"{c} {p3.rise_time_velocity_loop_s(p3.model_of_column(c)) * 1e3:.1f} ms" for c in data.COLUMNS), rows


def predictions_um(measures: dict[str, list[CircleMeasure]], settings: Sequence[Setting],
                   base: Scenario) -> dict[str, list[float]]:
    """The linear prediction of each measured circle's radius reduction, per setting [µm]."""
    model = model_of_scenario(base)
    return {s.name: [predicted_reduction_um(s.model(model), s.ff1, m.circle) for m in measures[s.name]]
            for s in settings}


def grid_rows(measures: dict[str, list[CircleMeasure]], settings: Sequence[Setting],
              base: Scenario) -> list[list[Any]]:
    """Per test: each setting's simulated radius reduction and its linear prediction [µm]."""
    predicted = predictions_um(measures, settings, base)
    rows = []
    for i, circle in enumerate(next(iter(measures.values()))):
        row: list[Any] = [circle.circle.label]
        for setting in settings:
            row += [round(measures[setting.name][i].radius_reduction_um, 2), round(predicted[setting.name][i], 2)]
        rows.append(row)
    return rows


def grid_text(measures: dict[str, list[CircleMeasure]], settings: Sequence[Setting], base: Scenario) -> str:
    """(c)/(d) per-test table and the aggregates, the paper's values beside (it gives no per-test figure)."""
    header = ["circle"] + [f"{s.name} {what}" for s in settings for what in ("sim um", "pred um")]
    lines = [format_table(header, grid_rows(measures, settings, base))]
    summaries = {s.name: summary_um(measures[s.name]) for s in settings}
    paper = {c: data.PAPER003_TABLE[c].radius_error_um for c in data.COLUMNS}
    rows = [[key] + [round(summaries[s.name][key], 1) for s in settings] + [paper["standard"], paper["optimal"]]
            for key in ("reduction_mean_um", "reduction_max_um", "deviation_mean_um", "deviation_max_um")]
    lines.append(format_table(["over the grid"] + [s.name for s in settings] + ["paper std", "paper opt"], rows))
    return "\n".join(lines)


def _timed_grid(executor: Any, base: Scenario, settings: Sequence[Setting],
                circles: Sequence[GridCircle]) -> tuple[dict[str, list[CircleMeasure]], float]:
    """The grid's measures and the wall time of the map (the executor warmed first: pool start not counted)."""
    grid_measures(executor, base, settings[:1], list(circles[:1]) * max(1, getattr(executor, "workers", 1) or 1))
    start = time.perf_counter()
    measures = grid_measures(executor, base, settings, circles)
    return measures, time.perf_counter() - start


def speed_figures(base: Scenario, plan: Plan, executor: Any, pooled_s: float, n_pooled: int,
                  measures: dict[str, list[CircleMeasure]]) -> dict[str, Any]:
    """Grid runs per second in one process (the standard column again) against the executor's, same values?"""
    with LocalExecutor(1) as one:
        again, one_s = _timed_grid(one, base, [column_setting("standard", OUR_GAIN_1_S)], plan.circles)
    one_rate, pooled_rate = len(plan.circles) / one_s, n_pooled / pooled_s
    return {"runs_per_s_one_process": one_rate, "runs_per_s_executor": pooled_rate,
            "speed_up": pooled_rate / one_rate, "workers": getattr(executor, "workers", None),
            "same_values": again["standard"] == measures["standard"], "load_1min": os.getloadavg()[0]}


def tuned_text(setting: Setting, result: TuningResult, base: Scenario, plan: Plan) -> str:
    """(d) the tuned setting, its margins, the search it came from."""
    margins = margins_of(base, setting)
    circles = ", ".join(c.label for c in plan.tune_circles)
    return (f"  tuned: K1 {setting.k1:.2f}, K2 {setting.k2:.3f}, k {setting.position_gain_1_s:.1f} /s, "
            f"ff1 {setting.ff1:.3f}; phase margin {margins['phase_margin_deg']:.1f} deg (>= 45), gain margin "
            f"{margins['gain_margin_db']:.1f} dB (>= 6), resonance peak {margins['resonance_peak_db']:.2f} dB; "
            f"feasible {result.feasible}\n  search: DE over K1 10..200, K2 0.1..5, k 10..300 /s, ff1 0..1; "
            f"{result.evaluations} evaluations ({plan.search.maxiter} generations x popsize {plan.search.popsize}, "
            f"seed {plan.search.seed}) on [{circles}]: mean largest |dev| {result.objective:.1f} um")


def beats_both(measures: dict[str, list[CircleMeasure]]) -> bool:
    """The tuned setting's radius reduction and largest |deviation| below both columns' at every test."""
    tuned = measures["tuned"]
    return all(t.max_abs_deviation_um < min(measures[c][i].max_abs_deviation_um for c in data.COLUMNS)
               and abs(t.radius_reduction_um) < min(measures[c][i].radius_reduction_um for c in data.COLUMNS)
               for i, t in enumerate(tuned))


def analytic_text(rows: list[dict[str, Any]]) -> str:
    """(e) the analytic optimum per reading and box, the paper's optimum in the title."""
    keys = ("lag", "box", "constraints", "k1", "k2", "zeta", "omega_n_rad_s", "objective_um", "at_edge")
    paper = data.PAPER003_TABLE["optimal"]
    return (f"  paper: K1 {paper.k1:g}, K2 {paper.k2:g}, zeta {paper.zeta:g}, omega_n {paper.omega_n_rad_s:g}; "
            f"ours (first_order_radius lag form, k 30 /s, T_ip 0, mean over the grid):\n"
            + format_table(keys, [[_round(r[k]) for k in keys] for r in rows]))


def simulate(options: argparse.Namespace, base: Scenario, plan: Plan, columns: Sequence[Setting]
             ) -> tuple[dict[str, list[CircleMeasure]], dict[str, Any], Setting, TuningResult]:
    """The grid of both columns, the speed figures, goal (1)'s search and the tuned grid, on one executor."""
    with make_executor(getattr(options, "workers", None), getattr(options, "scheduler", None)) as executor:
        measures, pooled_s = _timed_grid(executor, base, columns, plan.circles)
        speed = speed_figures(base, plan, executor, pooled_s, len(columns) * len(plan.circles), measures)
        tune_started = time.perf_counter()
        tuned, result = tune_on_grid(base, plan.tune_circles, plan.search, executor)
        speed["tune_evaluations_per_s"] = result.evaluations / (time.perf_counter() - tune_started)
        speed["circles_per_evaluation"] = len(plan.tune_circles)
        measures.update(grid_measures(executor, base, [tuned], plan.circles))
    return measures, speed, tuned, result


def paper003_bench(options: argparse.Namespace) -> int:
    """Run and print (a)-(e) and the speed; exit code 0 when goal (1) is met, 1 otherwise."""
    plan = make_plan(bool(getattr(options, "quick", False)))
    base = load_scenario(project_root() / SCENARIO)
    started = time.perf_counter()
    print("(a) Table 2, paper beside ours\n" + table2_text() + "\n" + readings_text(), flush=True)
    rise, rise_data = rise_text(base)
    print("(b) rise time to 1000 mm/min [s] (paper 0.16 -> 0.13)\n" + rise, flush=True)
    columns = [column_setting(c, OUR_GAIN_1_S) for c in data.COLUMNS]
    measures, speed, tuned, result = simulate(options, base, plan, columns)
    fitted = gain_for_mean_um(model_of_scenario(base), plan.circles)
    print_grid(base, plan, columns, measures, fitted)
    met = beats_both(measures)
    print(f"(d) goal (1), tuned on the simulated circular test\n{tuned_text(tuned, result, base, plan)}\n"
          + grid_text(measures, [*columns, tuned], base)
          + f"\n  tuned beats both columns at every test: {goal_text(met)}")
    optima = analytic_optima(plan.analytic_maxiter)
    print("(e) goal (2), the analytic objective's optimum per reading and box\n" + analytic_text(optima))
    print_speed(speed, time.perf_counter() - started)
    write_json(getattr(options, "json", None), {
        "bench": "paper003", "machine": machine(), "quick": plan.quick, "rise": rise_data, "speed": speed,
        "grid": {name: [asdict(m) for m in ms] for name, ms in measures.items()},
        "predicted_um": predictions_um(measures, [*columns, tuned], base),
        "tuned": asdict(tuned), "tuned_margins": margins_of(base, tuned), "goal_1_met": met,
        "gain_for_135_um": fitted, "analytic_optima": optima})
    return 0 if met else 1


def print_grid(base: Scenario, plan: Plan, columns: Sequence[Setting], measures: dict[str, list[CircleMeasure]],
               fitted: float | None) -> None:
    """(c) the columns over the grid, and the reading 'k such that the mean is 135 µm'."""
    print(f"(c) radius reduction over the grid, k {OUR_GAIN_1_S:g} /s, T_ip 10 ms exponential, T 1 ms "
          f"({len(plan.circles)} circles; sim: measured turn, pred: linear prediction)\n"
          + grid_text({c.name: measures[c.name] for c in columns}, columns, base))
    if fitted is None:
        print("  no position gain gives a predicted grid mean of 135 um")
        return
    model = model_of_scenario(base).with_(position_gain_x_1_s=fitted, position_gain_y_1_s=fitted)
    std, opt = (predicted_mean_um(p3.model_of_column(c, model), plan.circles) for c in data.COLUMNS)
    print(f"  reading 'mean over the grid': k = {fitted:.2f} /s makes the standard column's predicted mean "
          f"{std:.1f} um (paper 135); the optimal column is then {opt:.1f} um (paper 90), ratio {opt / std:.3f} "
          f"(paper {data.paper_ratio('radius_error_um'):.3f})")


def _workers_text(workers: int | None) -> str:
    """``2 workers`` for a local pool, ``a Dask cluster`` for an executor without a local worker count."""
    return f"{workers} workers" if workers else "a Dask cluster"


def print_speed(speed: dict[str, Any], wall_s: float) -> None:
    """The grid's runs per second in one process and through the executor, with the load."""
    print(f"speed: grid circles {speed['runs_per_s_one_process']:.2f} runs/s in one process, "
          f"{speed['runs_per_s_executor']:.2f} runs/s through the executor ({_workers_text(speed['workers'])}): "
          f"speed-up {speed['speed_up']:.2f}; same values {speed['same_values']}; 1-min load "
          f"{speed['load_1min']:.2f} on {os.cpu_count()} cores; goal (1)'s objective "
          f"{speed['tune_evaluations_per_s']:.2f} evaluations/s ({speed['circles_per_evaluation']} circles each, "
          f"through the executor); bench wall time {wall_s:.0f} s")
