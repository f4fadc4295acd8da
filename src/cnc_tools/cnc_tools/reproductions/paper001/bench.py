"""Bench ``paper001``: Tables 2 and 3 beside ours, learning curves, Fig. 8, the baselines, paper 000's machine.

Every run is on the engine (paper 001's scenarios, T = 1 ms, the unit reading
of ``docs/reproduction.md``: c in mm, the PID per µm). Learning runs carry
their state over through ``.npz`` files (``runs.learning_runs``). Printed:

1. Tables 2 and 3: ε_peak [mm] and ε_ISE (Σε² in mm² over the 1 ms samples)
   for the PID alone, every compensator stack after 1 run (PID, CCC) or after
   10 and 50 runs (networks, ILC), beside the paper's numbers, with each
   stack's change against our PID next to the paper's change against its PID;
2. the goal of issue 8 (the circle's peak at least −48 % within 10 runs) per
   stack, met or NOT met, and the paper's network in every stable unit
   reading (``reading_bench``) with where the paper's changes hold;
3. sensitivities of our network and of the ILC (circle);
4. Fig. 8: the learned network (and the ILC's feedforward) on the circle with
   the cutting load, beside the PID alone under the same load;
5. the network on paper 000's machine (its circle at 1.3 m/min, T = 10 ms);
6. the learning curves as ``learning_curves.png`` in the output folder, and
   the wall time.

``--quick``: 3 runs instead of 50 (columns after 2 and 3 runs), two
sensitivity rows, one process. Without it the sessions run in two worker
processes (each session is deterministic, so the numbers do not depend on it).
"""
from __future__ import annotations

import argparse
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.reproductions.paper001.data import TABLES, ContourResult, paper_result
from cnc_tools.reproductions.paper001.reading_bench import print_readings, reading_rows, reading_specs
from cnc_tools.reproductions.paper001.runs import (
    LATE_FROM_S,
    STACKS,
    Session,
    SessionSpec,
    run_sessions,
)
from cnc_tools.runs.folders import project_root, timestamp

#: The contours of Tables 2 and 3, in print order.
CONTOURS = ("line", "circle")
#: Stacks of the main tables, in print order.
TABLE_STACKS = ("pid", "nn-paper-mm", "nn-paper-um", "nn", "ccc", "ilc")
#: Issue 8's goal: the circle's ε_peak ratio NN@50/PID of Table 3, reached within the first checkpoint.
GOAL_RATIO = paper_result("circle", "pid+nn", 50).peak_mm / paper_result("circle").peak_mm


@dataclass(frozen=True)
class Variant:
    """A sensitivity row: a stack with some parameters changed (circle only)."""

    key: str
    label: str
    stack: str
    params: Mapping[str, Any]


#: Sensitivity rows (circle); ``--quick`` runs the first two.
VARIANTS: tuple[Variant, ...] = (
    Variant("eta_0.001", "η 0.001", "nn", {"eta": 1.0e-3}),
    Variant("eta_0.01", "η 0.01", "nn", {"eta": 1.0e-2}),
    Variant("eta_0.05", "η 0.05 (paper's)", "nn", {"eta": 0.05}),
    Variant("beta_1", "β 1 (paper's)", "nn", {"beta": 1.0}),
    Variant("beta_10", "β 10", "nn", {"beta": 10.0}),
    Variant("beta_100", "β 100", "nn", {"beta": 100.0}),
    Variant("inputs_dm", "position inputs per dm", "nn", {"position_input_scale_per_m": 100.0}),
    Variant("inputs_0.1mm", "position inputs per 0.1 mm", "nn", {"position_input_scale_per_m": 1.0e4}),
    Variant("u_unscaled", "u_N fed back in N (paper's)", "nn", {"output_input_scale": 1.0}),
    Variant("u_off", "u_N not fed back", "nn", {"output_input_scale": 0.0}),
    Variant("hidden_3", "3 hidden units", "nn", {"hidden_units": 3}),
    Variant("hidden_10", "10 hidden units", "nn", {"hidden_units": 10}),
    Variant("hidden_20", "20 hidden units", "nn", {"hidden_units": 20}),
    Variant("alpha_0", "α 0 (no momentum)", "nn", {"alpha": 0.0}),
    Variant("seed_1", "initial weights seed 1", "nn", {"seed": 1}),
    Variant("search", "random-search best", "nn",
            {"eta": 0.5193160855585465, "position_input_scale_per_m": 1.0e4, "beta": 0.0, "hidden_units": 10,
             "init_scale": 2.0, "alpha": 0.5}),
    Variant("search_eta", "the same, η 0.52", "nn",
            {"eta": 0.52, "position_input_scale_per_m": 1.0e4, "beta": 0.0, "hidden_units": 10,
             "init_scale": 2.0, "alpha": 0.5}),
    Variant("ilc_d0", "ILC d = 0", "ilc", {"advance_samples": 0}),
    Variant("ilc_d5", "ILC d = 5", "ilc", {"advance_samples": 5}),
    Variant("ilc_d18", "ILC d = 18 (Y's ω_n)", "ilc", {"advance_samples": 18}),
    Variant("ilc_d30", "ILC d = 30", "ilc", {"advance_samples": 30}),
    Variant("ilc_q20", "ILC Q 20 Hz", "ilc", {"cutoff_hz": 20.0}),
    Variant("ilc_l2", "ILC L 2 N/µm", "ilc", {"learning_gain": 2.0e6}),
    Variant("ccc_kd5", "CCC K_d × 5", "ccc", {"kd": 5.0e4}),
    Variant("ccc_x2", "CCC gains × 2", "ccc", {"kp": 1.0e7, "ki": 4.0e7, "kd": 2.0e4}),
)


@dataclass(frozen=True)
class Plan:
    """How much the bench runs and where it writes."""

    quick: bool
    checkpoints: tuple[int, int]
    out_dir: Path
    json: Path | None
    workers: int

    @property
    def runs(self) -> int:
        """Runs of a learning session."""
        return self.checkpoints[-1]


def plan_of(options: argparse.Namespace) -> Plan:
    """The plan from the bench options (``--quick``, ``--out``, ``--json``)."""
    quick = bool(getattr(options, "quick", False))
    out = getattr(options, "out", None) or project_root() / "bags" / "bench" / options.name / timestamp()
    workers = 1 if quick else min(2, os.cpu_count() or 1)
    return Plan(quick, (2, 3) if quick else (10, 50), Path(out), getattr(options, "json", None), workers)


# =========================================================================== sessions
def _runs_of(stack: str, plan: Plan) -> int:
    return plan.runs if STACKS[stack].learns else 1


def _spec(plan: Plan, key: str, scenario: str, stack: str, runs: int, **extra: Any) -> SessionSpec:
    return SessionSpec(key, scenario, stack, runs, str(plan.out_dir / "states" / key), **extra)


def main_specs(plan: Plan) -> list[SessionSpec]:
    """Tables 2 and 3 (every stack), paper 000's machine, the sensitivity rows."""
    specs = [_spec(plan, f"{contour}/{stack}", contour, stack, _runs_of(stack, plan))
             for contour in CONTOURS for stack in TABLE_STACKS]
    first = plan.checkpoints[0]
    specs += [_spec(plan, "paper000/pid", "paper000_circle", "pid", 1),
              _spec(plan, "paper000/nn", "paper000_circle", "file", first),
              _spec(plan, "paper000/nn-paper", "paper000_circle", "file", first,
                    params={"position_input_scale_per_m": 1.0e3, "output_input_scale": 1.0})]
    variants = VARIANTS[:2] if plan.quick else VARIANTS
    specs += [_spec(plan, f"sensitivity/{v.key}", "circle", v.stack, _runs_of(v.stack, plan), params=v.params)
              for v in variants]
    return specs


def cutting_specs(plan: Plan, sessions: Mapping[str, Session]) -> list[SessionSpec]:
    """Fig. 8: the PID, the network after the last run (frozen, learning, and frozen without the load), the ILC's."""
    network, ilc = str(sessions["circle/nn"].last_state()), str(sessions["circle/ilc"].last_state())
    return [_spec(plan, "fig8/pid", "circle_cutting", "pid", 1),
            _spec(plan, "fig8/nn-frozen", "circle_cutting", "nn", 1, state_in=network, freeze=True),
            _spec(plan, "fig8/nn-learning", "circle_cutting", "nn", 1, state_in=network),
            _spec(plan, "fig8/nn-frozen-no-load", "circle", "nn", 1, state_in=network, freeze=True),
            _spec(plan, "fig8/ilc-frozen", "circle_cutting", "ilc", 1, state_in=ilc, freeze=True)]


# =========================================================================== tables 2 and 3
def _change(value: float, reference: float) -> float:
    return value / reference - 1.0


def _pct(change: float | None) -> str:
    return "-" if change is None or change != change else f"{100.0 * change:+.0f} %"


def _checkpoints(stack: str, plan: Plan) -> tuple[int, ...]:
    return plan.checkpoints if STACKS[stack].learns else (1,)


def table_rows(contour: str, sessions: Mapping[str, Session], plan: Plan) -> list[dict[str, Any]]:
    """One row per stack and checkpoint: ours, the paper's where it has the column, changes against the PIDs.

    Our k-th checkpoint stands beside the paper's k-th column (after 10, 50 runs); with ``--quick`` ours
    come after fewer runs.
    """
    pid, paper_pid = sessions[f"{contour}/pid"].at(1), paper_result(contour)
    paper_runs = dict(zip(plan.checkpoints, (10, 50)))
    rows = []
    for stack in TABLE_STACKS:
        for runs in _checkpoints(stack, plan):
            session = sessions[f"{contour}/{stack}"]
            found = session.at(runs)
            paper = _paper_column(contour, stack, paper_runs.get(runs, 0))
            rows.append({"contour": contour, "stack": stack, "label": STACKS[stack].label, "asked_runs": runs,
                         **asdict(found), "guard_trips": _trips(session, runs),
                         "peak_change": _change(found.peak_mm, pid.peak_mm),
                         "ise_change": _change(found.ise_mm2, pid.ise_mm2),
                         "paper_peak_mm": None if paper is None else paper.peak_mm,
                         "paper_ise": None if paper is None else paper.ise,
                         "paper_peak_change": None if paper is None else _change(paper.peak_mm, paper_pid.peak_mm),
                         "paper_ise_change": None if paper is None else _change(paper.ise, paper_pid.ise)})
    return rows


def _trips(session: Session, runs: int) -> str:
    """How many of the first ``runs`` runs ended with the compensator's divergence guard tripped, as "k/n"."""
    done = session.runs[:runs]
    return f"{sum(1 for m in done if m.fault)}/{len(done)}"


def _paper_column(contour: str, stack: str, runs: int) -> ContourResult | None:
    """The paper's column for ``stack``: its PID for ours, its PID+NN for our networks, none for CCC/ILC."""
    if stack == "pid":
        return paper_result(contour)
    if STACKS[stack].method == "neural":
        return paper_result(contour, "pid+nn", runs)
    return None


def print_table(contour: str, rows: Sequence[Mapping[str, Any]], plan: Plan) -> None:
    """Our rows of one contour beside the paper's table."""
    number = 2 if contour == "line" else 3
    paper = " / ".join(f"{r.peak_mm:g} mm, {r.ise:g}" for r in TABLES[contour])
    print(f"\nTable {number}, {contour}: ε_peak [mm] over the whole run; "
          f"ε_ISE = Σε² [mm²] over the 1 ms samples; paper PID / NN@10 / NN@50: {paper}")
    print("  Δ: change against the PID of the same table (ours against ours, the paper's against the paper's); "
          f"peak moving: while the reference moves; late RMS [mm]: from {LATE_FROM_S:g} s while it moves"
          + ("" if not plan.quick else f"; --quick: ours after {plan.checkpoints} runs beside the paper's 10, 50"))
    print(format_table(
        ["stack", "runs", "ε_peak", "paper", "Δ peak", "paper Δ", "ε_ISE", "paper", "Δ ISE", "paper Δ",
         "peak moving", "late RMS", "max |u_c| N", "guard trips", "diverged"],
        [[r["label"], r["run"], f"{r['peak_mm']:.4f}", _paper_text(r["paper_peak_mm"]), _pct(r["peak_change"]),
          _pct(r["paper_peak_change"]), f"{r['ise_mm2']:.4g}", _paper_text(r["paper_ise"]), _pct(r["ise_change"]),
          _pct(r["paper_ise_change"]), f"{r['peak_motion_mm']:.4f}", f"{r['late_rms_mm']:.4f}",
          f"{r['compensation_max']:.4g}",
          r["guard_trips"], "yes" if r["diverged"] else "-"] for r in rows]))


def _paper_text(value: float | None) -> str:
    return "-" if value is None else f"{value:g}"


def goal_rows(sessions: Mapping[str, Session], plan: Plan) -> list[dict[str, Any]]:
    """Issue 8's goal per stack: circle ε_peak ratio to the PID within the first checkpoint ≤ the paper's at 50."""
    pid = sessions["circle/pid"].at(1).peak_mm
    rows = []
    for stack in TABLE_STACKS[1:]:
        runs = plan.checkpoints[0] if STACKS[stack].learns else 1
        session = sessions[f"circle/{stack}"]
        best = min(m.peak_mm for m in session.runs[:runs])
        ratio = session.at(runs).peak_mm / pid
        rows.append({"stack": stack, "label": STACKS[stack].label, "runs": runs, "ratio": ratio,
                     "best_ratio": best / pid, "met": bool(ratio <= GOAL_RATIO)})
    return rows


def print_goal(rows: Sequence[Mapping[str, Any]]) -> None:
    """Met / NOT met per stack, and for the best one."""
    print(f"\ngoal (issue 8): circle ε_peak at most {GOAL_RATIO:.3f} × the PID's (the paper's −48 % after 50 runs) "
          "after the first checkpoint")
    print(format_table(["stack", "after runs", "ε_peak / PID", "best run so far", "goal"],
                       [[r["label"], r["runs"], f"{r['ratio']:.3f}", f"{r['best_ratio']:.3f}", goal_text(r["met"])]
                        for r in rows]))
    best = min(rows, key=lambda r: r["ratio"])
    print(f"  best stack: {best['label']} ({_pct(best['ratio'] - 1.0)}): {goal_text(best['met'])}")


# =========================================================================== sensitivities, Fig. 8, paper 000
def sensitivity_rows(sessions: Mapping[str, Session], plan: Plan) -> list[dict[str, Any]]:
    """Per variant (and the stated stacks first): changed parameters, circle ε_peak and ISE changes per checkpoint."""
    pid = sessions["circle/pid"].at(1)
    variants = VARIANTS[:2] if plan.quick else VARIANTS
    listed: list[tuple[str, str, str, dict[str, Any]]] = [
        (f"circle/{s}", STACKS[s].label + " (stated)", s, {}) for s in ("nn", "ilc", "ccc")]
    listed += [(f"sensitivity/{v.key}", v.label, v.stack, dict(v.params)) for v in variants]
    rows = []
    for key, label, stack, params in listed:
        session = sessions[key]
        row: dict[str, Any] = {"key": key, "label": label, "stack": stack, "params": params,
                               "guard_trips": _trips(session, len(session.runs)),
                               "diverged_runs": sum(1 for m in session.runs if m.diverged), "at": {}}
        for runs in _checkpoints(stack, plan):
            found = session.at(runs)
            row["at"][runs] = {"peak_change": _change(found.peak_mm, pid.peak_mm),
                               "ise_change": _change(found.ise_mm2, pid.ise_mm2), "run": found.run}
        rows.append(row)
    return rows


def print_sensitivities(rows: Sequence[Mapping[str, Any]], plan: Plan) -> None:
    """One line per variant: what changed and the circle's changes against the PID."""
    first, last = plan.checkpoints
    print("\nsensitivities (circle; one change against the stated stack; Δ against the PID alone)")
    cells = []
    for r in rows:
        changed = ", ".join(f"{k} {v:.7g}" for k, v in r["params"].items()) or "-"
        a = r["at"].get(first, r["at"].get(1))
        b = r["at"].get(last, a)
        cells.append([r["label"], changed, a["run"], _pct(a["peak_change"]), _pct(a["ise_change"]), b["run"],
                      _pct(b["peak_change"]), _pct(b["ise_change"]), r["guard_trips"], r["diverged_runs"]])
    print(format_table(["variant", "changed", "runs", "Δ peak", "Δ ISE", "runs", "Δ peak", "Δ ISE", "guard trips",
                        "diverged runs"],
                       cells))


#: Fig. 8 rows: session key, label.
FIG8_ROWS = (("fig8/pid", "PID, cutting load"), ("fig8/nn-frozen", "PID+NN ours, learned, frozen, cutting load"),
             ("fig8/nn-learning", "PID+NN ours, learned, still learning, cutting load"),
             ("fig8/nn-frozen-no-load", "PID+NN ours, learned, frozen, no load"),
             ("fig8/ilc-frozen", "PID+ILC, learned, frozen, cutting load"))


def fig8_rows(sessions: Mapping[str, Session]) -> list[dict[str, Any]]:
    """Fig. 8's runs with the PID alone without the load for reference; changes against the PID under the load."""
    cut = sessions["fig8/pid"].at(1)
    listed = [("circle/pid", "PID, no load")] + list(FIG8_ROWS)
    return [{"key": key, "label": label, **asdict(found := sessions[key].at(1)),
             "peak_change": _change(found.peak_mm, cut.peak_mm),
             "late_rms_change": _change(found.late_rms_mm, cut.late_rms_mm)} for key, label in listed]


def print_fig8(rows: Sequence[Mapping[str, Any]], plan: Plan) -> None:
    """Fig. 8: the learned compensators under the cutting load beside the PID."""
    print(f"\nFig. 8: circle with the cutting load (scenarios/paper001/circle_cutting.yaml), weights learned over "
          f"{plan.runs} runs on the plain circle; 'late' = from {LATE_FROM_S:g} s on while the reference moves "
          "(after the start transient, before the stop); "
          "Δ against the PID under the load")
    print(format_table(["run", "ε_peak", "Δ peak", "ε_ISE", "late peak", "late RMS", "Δ late RMS"],
                       [[r["label"], f"{r['peak_mm']:.4f}", _pct(r["peak_change"]), f"{r['ise_mm2']:.4g}",
                         f"{r['late_peak_mm']:.4f}", f"{r['late_rms_mm']:.4f}", _pct(r["late_rms_change"])]
                        for r in rows]))


def paper000_rows(sessions: Mapping[str, Session], plan: Plan) -> list[dict[str, Any]]:
    """Paper 000's circle: the PID, the scenario file's network and the paper's scaling after the first checkpoint."""
    pid = sessions["paper000/pid"].at(1)
    listed = (("paper000/pid", "PID", 1), ("paper000/nn", "PID+NN (scenario file)", plan.checkpoints[0]),
              ("paper000/nn-paper", "PID+NN, inputs in mm, u_N unscaled (paper's)", plan.checkpoints[0]))
    return [{"key": key, "label": label, **asdict(found := sessions[key].at(runs)),
             "guard_trips": _trips(sessions[key], runs), "peak_change": _change(found.peak_mm, pid.peak_mm),
             "ise_change": _change(found.ise_mm2, pid.ise_mm2)} for key, label, runs in listed]


def print_paper000(rows: Sequence[Mapping[str, Any]]) -> None:
    """PID and PID+NN on paper 000's machine."""
    print("\npaper 000's machine (scenarios/paper001/paper000_circle_nn.yaml: circle r = 20 mm at 1.3 m/min, "
          "DAC drives, T = 10 ms; ε_ISE = Σε² [mm²] over its 10 ms samples)")
    print(format_table(["stack", "runs", "ε_peak", "Δ peak", "ε_ISE", "Δ ISE", "max |u_c| DAC", "guard trips",
                        "diverged"],
                       [[r["label"], r["run"], f"{r['peak_mm']:.4f}", _pct(r["peak_change"]), f"{r['ise_mm2']:.4g}",
                         _pct(r["ise_change"]), f"{r['compensation_max']:.4g}",
                         r["guard_trips"], "yes" if r["diverged"] else "-"] for r in rows]))


# =========================================================================== learning curves
#: Stacks drawn in the learning-curve figure.
CURVE_STACKS = ("nn-paper-mm", "nn-paper-um", "nn", "ilc")


def plot_learning_curves(sessions: Mapping[str, Session], path: Path) -> Path:
    """ε_peak and ε_ISE per run as a ratio to the PID (log scale), both contours; the paper's NN ratios as marks."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True)
    for column, contour in enumerate(CONTOURS):
        pid = sessions[f"{contour}/pid"].at(1)
        for row, (field, name) in enumerate((("peak_mm", "ε_peak"), ("ise_mm2", "ε_ISE"))):
            ax = axes[row][column]
            for stack in CURVE_STACKS:
                runs = sessions[f"{contour}/{stack}"].runs
                ax.plot([m.run for m in runs], [getattr(m, field) / getattr(pid, field) for m in runs],
                        marker=".", label=STACKS[stack].label)
            paper = [paper_result(contour, "pid+nn", n) for n in (10, 50)]
            reference = getattr(paper_result(contour), "peak_mm" if row == 0 else "ise")
            ax.plot([10, 50], [getattr(p, "peak_mm" if row == 0 else "ise") / reference for p in paper], "k*",
                    markersize=12, label="paper, PID+NN")
            ax.axhline(1.0, color="grey", linewidth=0.8)
            ax.set_yscale("log")
            ax.set_title(f"{contour}: {name} / PID ({name} PID = {getattr(pid, field):.4g})")
            ax.set_xlabel("run")
    axes[0][0].legend(fontsize=8)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


# =========================================================================== the bench
def print_stacks() -> None:
    """Every stack's compensator and the parameters we set (the configs' defaults for the rest)."""
    print("\nstacks (parameters set by us; the rest are the compensator config's defaults):")
    for stack in STACKS.values():
        params = ", ".join(f"{k} {v:g}" for k, v in stack.params.items()) or "-"
        print(f"  {stack.label:20s} {stack.method or 'none':9s} {params}\n  {'':20s} {'':9s} ({stack.why})")


def paper001_bench(options: argparse.Namespace) -> int:
    """Tables 2 and 3, the goal, sensitivities, Fig. 8, paper 000's machine, learning curves, wall time."""
    started = time.perf_counter()
    plan = plan_of(options)
    print(f"paper001: engine, T = 1 ms; learning sessions of {plan.runs} runs (state carried over in .npz files); "
          f"{plan.workers} process(es); files in {plan.out_dir}", flush=True)
    readings = reading_specs(plan.checkpoints, str(plan.out_dir / "states"), plan.quick)
    sessions = run_sessions(main_specs(plan) + readings, plan.workers)
    sessions.update(run_sessions(cutting_specs(plan, sessions), plan.workers))
    tables = {contour: table_rows(contour, sessions, plan) for contour in CONTOURS}
    figures = {"goal": goal_rows(sessions, plan), "sensitivities": sensitivity_rows(sessions, plan),
               "fig8": fig8_rows(sessions), "paper000": paper000_rows(sessions, plan),
               "readings": reading_rows(sessions, plan.checkpoints, plan.quick)}
    print_stacks()
    for contour in CONTOURS:
        print_table(contour, tables[contour], plan)
    print_goal(figures["goal"])
    print_readings(figures["readings"])
    print_sensitivities(figures["sensitivities"], plan)
    print_fig8(figures["fig8"], plan)
    print_paper000(figures["paper000"])
    curves = plot_learning_curves(sessions, plan.out_dir / "learning_curves.png")
    wall_s = time.perf_counter() - started
    print(f"\nlearning curves: {curves}")
    print(f"wall time: {wall_s:.1f} s for {sum(len(s.runs) for s in sessions.values())} engine runs "
          f"(1-min load {os.getloadavg()[0]:.2f})")
    write_json(plan.json, {"bench": "paper001", "machine": machine(), "wall_time_s": wall_s,
                           "plan": {"quick": plan.quick, "checkpoints": plan.checkpoints, "workers": plan.workers},
                           "stacks": {s.name: {"method": s.method, "params": dict(s.params)} for s in STACKS.values()},
                           "tables": tables, **figures, "sessions": {k: s.to_json() for k, s in sessions.items()}})
    return 0
