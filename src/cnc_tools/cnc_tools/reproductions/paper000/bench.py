"""Benches ``paper000-pid`` and ``paper000``: paper 000's Table 5 and experiments beside ours.

``paper000-pid``
    The six Table 5 scenarios (line, circle, corner × low, high feed) with the
    paper's PID, every seed through the node graph (recorded, scored from the
    bag), or the engine with ``--engine``; our max and RMS contour error [BLU] beside
    Table 5's PID columns and the ratio ours/paper.
``paper000``
    Table 5 for PID and FLC over several seeds (mean ± sample standard
    deviation; the first seed through the node graph unless ``--engine``,
    the others in the engine), the FLC/PID ratios beside the paper's, the two
    experiments as simulations, PID+ff and FLC+ff, the FLC with every
    alternative rule base, PNG figures of the kind of Figs. 9-11, wall time.

Scored view (``paper000_runs.VIEWS["paper"]``): the distance to the contour of
Eqs. 9/10 (a line's ends extended: Eq. 9 is the whole line) while the
reference moves, start transient included. ``docs/reproduction.md`` lists
every assumption and what it changes.

Options of ``cnc-contour bench``: ``--quick`` (line_low only, one seed),
``--engine``, ``--seeds N``, ``--out``, ``--json``.
"""
from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.core.units import M_PER_BLU_PAPER000
from cnc_tools.analysis.report import write_report
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.reproductions.paper000.data import EXPERIMENTS, TABLE5, Table5Row
from cnc_tools.reproductions.paper000.runs import CONTROLLERS, VIEWS
from cnc_tools.reproductions.paper000.sweep import (
    Case,
    Settings,
    Sweep,
    SweepPlan,
    run_sweep,
    settings_of,
    stat_text,
    table5_cases,
    wins,
)
from cnc_tools.run_record import RecordedRun
from cnc_tools.runs.folders import project_root

#: Seeds of ``paper000`` when ``--seeds`` is not given.
DEFAULT_SEEDS = 5
#: Table 5 cases drawn as Figs. 9-11 (line 0.4 m/min, circle 0.4 and 1.3 m/min, corner 0.3 m/min).
FIGURE_CASES = ("line_low", "circle_low", "circle_high", "corner_low")
#: The FLC's input range, Table 3's outermost centres: |e| [BLU] and |Δe| [BLU per sample].
FLC_E_LIMIT_BLU, FLC_DE_LIMIT_BLU = 21.0, 4.5
#: The alternative rule bases (``flc:<name>``).
RULE_BASE_CONTROLLERS = tuple(name for name in CONTROLLERS if name.startswith("flc:"))


def experiment_cases(quick: bool) -> list[Case]:
    """The two experiments' scenarios (``--quick``: the line only)."""
    chosen = EXPERIMENTS[:1] if quick else EXPERIMENTS
    return [Case(e.name, project_root() / e.scenario) for e in chosen]


def _rows(cases: Sequence[Case]) -> list[Table5Row]:
    names = {c.name for c in cases}
    return [row for row in TABLE5 if row.case in names]


def _how(plan: SweepPlan) -> str:
    if plan.graph_seeds == 0:
        return "engine (in-process), scored by the project scorer"
    if plan.graph_seeds >= len(plan.seeds):
        return "node graph, recorded to MCAP and scored from the bag"
    return "first seed: node graph, recorded to MCAP and scored from the bag; other seeds: engine"


# =========================================================================== paper000-pid
def pid_table(sweep: Sweep, rows: Sequence[Table5Row]) -> list[dict[str, Any]]:
    """Rows of the PID table: ours (mean, per seed), the paper's, ours/paper; the project's whole-run score too."""
    out = []
    for row in rows:
        entry: dict[str, Any] = {"case": row.case, "contour": row.contour, "feed": row.feed,
                                 "feed_m_min": row.feed_m_min}
        for metric in ("max", "rms"):
            values = sweep.values(row.case, "pid", metric)
            paper = row.paper_value("pid", metric)
            entry[metric] = {"ours_blu": values, "ours_mean_blu": sweep.mean(row.case, "pid", metric),
                             "paper_blu": paper, "ratio_ours_to_paper": sweep.mean(row.case, "pid", metric) / paper,
                             "whole_run_blu": sweep.values(row.case, "pid", metric, "whole_run")}
        out.append(entry)
    return out


def print_pid_table(table: Sequence[dict[str, Any]]) -> None:
    """Our PID beside Table 5's PID columns."""
    print(format_table(["contour", "feed", "max ours", "max paper", "ours/paper", "RMS ours", "RMS paper",
                        "ours/paper", "whole-run max", "whole-run RMS"], [_pid_cells(t) for t in table]))


def _pid_cells(entry: dict[str, Any]) -> list[object]:
    cells: list[object] = [entry["contour"], f"{entry['feed']} {entry['feed_m_min']:g}"]
    for metric in ("max", "rms"):
        m = entry[metric]
        cells += [stat_text(m["ours_blu"]), f"{m['paper_blu']:.1f}", f"{m['ratio_ours_to_paper']:.2f}"]
    return cells + [stat_text(entry["max"]["whole_run_blu"]), stat_text(entry["rms"]["whole_run_blu"])]


def paper000_pid_bench(options: argparse.Namespace) -> int:
    """Table 5's PID columns: the six scenarios with the paper's PID, recorded and scored."""
    started = time.perf_counter()
    settings = settings_of(options, default_seeds=1)
    cases = table5_cases(settings.quick)
    plan = settings.plan(graph_seeds=len(settings.seeds))
    print(f"paper000-pid: {len(cases)} scenarios x seeds {list(settings.seeds)}; {_how(plan)}; "
          f"run files in {settings.out_dir}", flush=True)
    sweep = run_sweep(cases, ["pid"], plan)
    table = pid_table(sweep, _rows(cases))
    print(f"\nPID (Eq. 14, Table 4 gains), contour error [BLU = 10 µm], {VIEWS['paper'].description}; "
          f"mean ± sample std over seeds; 'whole run': {VIEWS['whole_run'].description}")
    print_pid_table(table)
    _print_agreement(sweep)
    figures = _figures(sweep, [c.name for c in cases], ["pid"], settings.out_dir / "figures")
    wall_s = time.perf_counter() - started
    print(f"\nfigures: {figures}\nwall time: {wall_s:.1f} s")
    write_json(settings.json, {"bench": "paper000-pid", "seeds": list(settings.seeds), "engine": settings.engine,
                               "machine": machine(), "wall_time_s": wall_s, "table": table, "runs": sweep.to_json()})
    return 0


# =========================================================================== paper000
def compare_table(sweep: Sweep, rows: Sequence[Table5Row], pid: str = "pid", flc: str = "flc",
                  paper: bool = True) -> list[dict[str, Any]]:
    """Per row: both controllers' max/RMS per seed, the FLC/PID ratios, the paper's where it has them."""
    out = []
    for row in rows:
        entry: dict[str, Any] = {"case": row.case, "pid": pid, "flc": flc}
        for metric in ("max", "rms"):
            a, b = sweep.values(row.case, pid, metric), sweep.values(row.case, flc, metric)
            entry[metric] = {"pid_blu": a, "flc_blu": b, "flc_to_pid": sweep.mean(row.case, flc, metric)
                             / sweep.mean(row.case, pid, metric), "flc_not_worse_seeds": wins(b, a)}
            if paper:
                entry[metric].update(paper_pid_blu=row.paper_value("pid", metric),
                                     paper_flc_blu=row.paper_value("flc", metric),
                                     paper_flc_to_pid=row.paper_value("flc", metric) / row.paper_value("pid", metric))
        out.append(entry)
    return out


def print_compare_table(table: Sequence[dict[str, Any]], paper: bool = True) -> None:
    """Max, then RMS: both controllers (and the paper's), the FLC/PID ratios, seeds where the FLC is not worse."""
    for metric, title in (("max", "max"), ("rms", "RMS")):
        header = ["case", f"{title} PID", f"{title} FLC"] + (["paper PID", "paper FLC"] if paper else [])
        header += ["FLC/PID"] + (["paper FLC/PID"] if paper else []) + ["FLC<=PID seeds"]
        rows = []
        for t in table:
            m = t[metric]
            cells: list[object] = [t["case"], stat_text(m["pid_blu"]), stat_text(m["flc_blu"])]
            cells += [f"{m['paper_pid_blu']:.1f}", f"{m['paper_flc_blu']:.1f}"] if paper else []
            cells += [f"{m['flc_to_pid']:.2f}"] + ([f"{m['paper_flc_to_pid']:.2f}"] if paper else [])
            rows.append(cells + [m["flc_not_worse_seeds"]])
        print(format_table(header, rows))


def experiment_table(sweep: Sweep, quick: bool) -> list[dict[str, Any]]:
    """The experiments: PID and FLC max/RMS, our PID:FLC ratios beside the paper's."""
    out = []
    for experiment in EXPERIMENTS[:1] if quick else EXPERIMENTS:
        entry: dict[str, Any] = {"experiment": experiment.name, "description": experiment.description}
        for metric, paper in (("max", experiment.max_ratio_pid_to_flc), ("rms", experiment.rms_ratio_pid_to_flc)):
            entry[metric] = {"pid_blu": sweep.values(experiment.name, "pid", metric),
                             "flc_blu": sweep.values(experiment.name, "flc", metric),
                             "pid_to_flc": sweep.mean(experiment.name, "pid", metric)
                             / sweep.mean(experiment.name, "flc", metric), "paper_pid_to_flc": paper}
        out.append(entry)
    return out


def print_experiment_table(table: Sequence[dict[str, Any]]) -> None:
    """PID:FLC ratios (> 1: the FLC is better), ours beside the paper's."""
    def paper(value: float | None) -> str:
        return "-" if value is None else f"{value:.1f}"

    print(format_table(
        ["experiment", "max PID", "max FLC", "PID:FLC", "paper", "RMS PID", "RMS FLC", "PID:FLC", "paper"],
        [[t["experiment"], stat_text(t["max"]["pid_blu"]), stat_text(t["max"]["flc_blu"]),
          f"{t['max']['pid_to_flc']:.2f}", paper(t["max"]["paper_pid_to_flc"]), stat_text(t["rms"]["pid_blu"]),
          stat_text(t["rms"]["flc_blu"]), f"{t['rms']['pid_to_flc']:.2f}", paper(t["rms"]["paper_pid_to_flc"])]
         for t in table]))


def rule_base_table(sweep: Sweep, rows: Sequence[Table5Row]) -> list[dict[str, Any]]:
    """Every rule base's FLC max/RMS per seed and its ratio to the PID."""
    out = []
    for row in rows:
        for name in ("flc", *RULE_BASE_CONTROLLERS):
            out.append({"case": row.case, "controller": name, **{
                metric: {"blu": sweep.values(row.case, name, metric),
                         "flc_to_pid": sweep.mean(row.case, name, metric) / sweep.mean(row.case, "pid", metric)}
                for metric in ("max", "rms")}})
    return out


def print_rule_base_table(table: Sequence[dict[str, Any]]) -> None:
    """One line per case and rule base."""
    print(format_table(["case", "rule base", "max", "max/PID", "RMS", "RMS/PID"], [
        [t["case"], "paper000" if t["controller"] == "flc" else t["controller"][4:], stat_text(t["max"]["blu"]),
         f"{t['max']['flc_to_pid']:.2f}", stat_text(t["rms"]["blu"]), f"{t['rms']['flc_to_pid']:.2f}"]
        for t in table]))


def following_table(sweep: Sweep, rows: Sequence[Table5Row]) -> list[dict[str, Any]]:
    """First seed, whole run, PID and FLC: peak |following error| and |command| per axis, share in the FLC's sets."""
    return [{"case": row.case, "controller": name,
             **_following(sweep.first_runs[(row.case, name)]["whole_run"][0])}
            for row in rows for name in ("pid", "flc")]


def _following(run: RecordedRun) -> dict[str, Any]:
    axes = run.axis_names
    error_blu = np.array([run.commands[a].error_m for a in axes]) / M_PER_BLU_PAPER000  # (n_axes, N)
    change_blu = np.diff(error_blu, axis=1, prepend=0.0)
    inside = (np.abs(error_blu) <= FLC_E_LIMIT_BLU) & (np.abs(change_blu) <= FLC_DE_LIMIT_BLU)
    return {"peak_error_blu": {a: float(np.max(np.abs(e))) for a, e in zip(axes, error_blu)},
            "peak_command_dac": {a: float(np.max(np.abs(run.commands[a].command))) for a in axes},
            "inside_flc_sets": float(np.mean(inside))}


def print_following_table(table: Sequence[dict[str, Any]]) -> None:
    """Peak following error and command per axis; share of axis samples inside the FLC's input sets."""
    print(format_table(["case", "law", "peak |e| [BLU]", "peak |u| [DAC]", "inside FLC sets"], [
        [t["case"], CONTROLLERS[t["controller"]].label, "/".join(f"{v:.1f}" for v in t["peak_error_blu"].values()),
         "/".join(f"{v:.0f}" for v in t["peak_command_dac"].values()), f"{100 * t['inside_flc_sets']:.1f} %"]
        for t in table]))


def _print_agreement(sweep: Sweep) -> None:
    if sweep.graph_vs_engine_blu:
        print(f"node graph vs engine, same seed, same scorer: largest difference "
              f"{max(sweep.graph_vs_engine_blu):.3g} BLU over {len(sweep.graph_vs_engine_blu)} runs")


def _figures(sweep: Sweep, cases: Sequence[str], controllers: Sequence[str], folder: Path) -> Path:
    """Figs. 9-11 analogues: per case, the first seed's runs side by side (XY ×M, error vs time, commands)."""
    for case in cases:
        items = [sweep.first_runs[(case, name)]["paper"] for name in controllers]
        runs = [_labelled(run, CONTROLLERS[name].label) for (run, _), name in zip(items, controllers)]
        write_report(runs, folder / case, scores=[score for _, score in items],
                     figures=["xy", "error_time", "tracking"])
    return folder


def _labelled(run: RecordedRun, label: str) -> RecordedRun:
    return dataclasses.replace(run, name=label)


def paper000_bench(options: argparse.Namespace) -> int:
    """Table 5 for PID and FLC, the experiments, feedforward, the rule bases, figures and wall time."""
    started = time.perf_counter()
    settings = settings_of(options, default_seeds=DEFAULT_SEEDS)
    cases, experiments = table5_cases(settings.quick), experiment_cases(settings.quick)
    rows = _rows(cases)
    print(f"paper000: seeds {list(settings.seeds)}; main table: {_how(settings.plan(graph_seeds=1))}; "
          f"run files in {settings.out_dir}", flush=True)
    sweep = run_sweep(cases, ["pid", "flc"], settings.plan(graph_seeds=1))
    run_sweep(experiments, ["pid", "flc"], settings.plan(graph_seeds=0), sweep)
    run_sweep(cases, ["pid+ff", "flc+ff", *RULE_BASE_CONTROLLERS], settings.plan(graph_seeds=0), sweep)
    figures = _figures(sweep, [c for c in FIGURE_CASES if c in {k.name for k in cases}] or [cases[0].name],
                       ["pid", "flc"], settings.out_dir / "figures")
    tables = _print_all(sweep, rows, settings)
    wall_s = time.perf_counter() - started
    print(f"\nfigures (Figs. 9-11 kind: xy_trace, contour_error_time, tracking per case): {figures}")
    print(f"wall time: {wall_s:.1f} s")
    write_json(settings.json, {"bench": "paper000", "seeds": list(settings.seeds), "engine": settings.engine,
                               "machine": machine(), "wall_time_s": wall_s, **tables, "runs": sweep.to_json()})
    return 0


def _print_all(sweep: Sweep, rows: Sequence[Table5Row], settings: Settings) -> dict[str, Any]:
    """Print every table of ``paper000``; return them as plain data."""
    tables = {"table5": compare_table(sweep, rows), "experiments": experiment_table(sweep, settings.quick),
              "feedforward": compare_table(sweep, rows, "pid+ff", "flc+ff", paper=False),
              "rule_bases": rule_base_table(sweep, rows), "following": following_table(sweep, rows)}
    print(f"\nTable 5, contour error [BLU = 10 µm], {VIEWS['paper'].description}; mean ± sample std over "
          f"{len(settings.seeds)} seeds; FLC<=PID: seeds where the FLC is not worse")
    print_compare_table(tables["table5"])
    _print_agreement(sweep)
    print("\nexperiments (section 4.2) as simulations on the paper-000 plant; PID:FLC > 1 means the FLC is better")
    print_experiment_table(tables["experiments"])
    print("\nbeyond the paper: with feedforward ff1 = 1/K, ff2 = τ/K (nominal K, τ per axis)")
    print_compare_table(tables["feedforward"], paper=False)
    print("\nrule-base sensitivity (fuzzy.RULE_BASES; docs/fuzzy_rule_base.md); ratios to the PID")
    print_rule_base_table(tables["rule_bases"])
    print(f"\nseed 1, whole run: peak following error and command per axis (x/y); share of axis samples with "
          f"|e| <= {FLC_E_LIMIT_BLU:g} BLU and |de| <= {FLC_DE_LIMIT_BLU:g} BLU (inside the FLC's sets, Table 3)")
    print_following_table(tables["following"])
    return tables


