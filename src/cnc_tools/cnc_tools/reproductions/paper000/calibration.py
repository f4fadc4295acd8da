"""Bench ``paper000-calibrated``: the plant's open assumptions fitted to Table 5's PID column, then PID vs FLC.

Paper 000 leaves four things about its plant open that move Table 5 (see
``assumptions.py``). Each is a :class:`PlantParameter` of :data:`PARAMETERS`:

- ``ke``: the encoder gain K_e [count/BLU] (``servo.counts_per_m`` = 1e5·K_e);
- ``lag_s``: an unmodelled first-order lag [s], added to each axis's Table 2
  τ (a lag τ_l in series, 1/((τs+1)(τ_l s+1)), has the same low-frequency
  phase as one lag τ + τ_l; the plant has no second lag to put it in);
- ``friction_scale``: a factor on Eq. 15's friction (the ±8 % draw on top);
- ``saturation_dac``: a saturation of the drive's input [DAC] (127: none
  beyond the 8-bit DAC's own).

:class:`PidColumnObjective` runs the six Table 5 cases with the paper's PID
(Table 4) in the engine, scores them in the ``paper`` view with the project's
scorer, and returns the RMS over the twelve PID figures (max, RMS per case) of
ln(ours / paper). It holds the PID column only (:func:`pid_targets`): the FLC
column is never read by the fit. :func:`fit` minimises it with the tuner's
:func:`~cnc_tools.tuning.solve.solve` (differential evolution) from several DE
seeds; the spread of the optima says how well the data pins each parameter.
Then :func:`compare` reruns PID and FLC (Tables 1, 3, 4 unchanged) on the
calibrated plant over several plant seeds; a run the machine faults (a
following-error trip) is a row of the comparison with its axis, time and
reason, counted apart and never a win for either law. Every engine run goes
through an executor (``--workers``, ``--scheduler``).
"""
from __future__ import annotations

import argparse
import math
import statistics
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from cnc_contour_control.core.config import require_choice
from cnc_contour_control.core.errors import CncError, ConfigError
from cnc_tools.analysis.scoring import score_run
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.reproductions.paper000.data import TABLE2_AXES, TABLE5, Table5Row
from cnc_tools.reproductions.paper000.runs import VIEWS, apply_view, blu, get_controller, scenario_for
from cnc_tools.reproductions.paper000.sweep import stat_text, wins
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.executor import Executor, make_executor
from cnc_tools.runs.faults import FaultRow, fault_row
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import Scenario, merge
from cnc_tools.tuning.problem import DesignVariable, check_unique
from cnc_tools.tuning.solve import TuningResult, solve

#: Counts per metre at K_e = 1 count/BLU (BLU = 10 µm).
COUNTS_PER_M_AT_KE_1 = 1.0e5
#: A bound within this fraction of the box's width from a fitted value counts as "on the bound".
ON_BOUND_FRACTION = 0.01
#: (case, metric) -> a figure [BLU]; metric is ``max`` or ``rms``.
Figures = dict[tuple[str, str], float]
#: One comparison run: (max, RMS) [BLU], or the fault that stopped it.
CaseResult = tuple[float, float] | FaultRow
#: (case, ``pid``/``flc``) -> one result per plant seed, in the seeds' order.
Comparison = Mapping[tuple[str, str], Sequence[CaseResult]]


# =========================================================================== the open assumptions
def _ke(value: float) -> dict[str, Any]:
    return {"servo": {"counts_per_m": COUNTS_PER_M_AT_KE_1 * value}}


def _lag(value: float) -> dict[str, Any]:
    return {"plant": {"axis_overrides": {axis: {"time_constant_s": tau_s + value}
                                         for axis, (_, tau_s) in TABLE2_AXES.items()}}}


def _per_axis(key: str) -> Callable[[float], dict[str, Any]]:
    return lambda value: {"plant": {"axis_overrides": {axis: {key: value} for axis in TABLE2_AXES}}}


@dataclass(frozen=True)
class PlantParameter:
    """An open assumption of the plant: its unit, the shipped value, its domain and default search box."""

    name: str
    unit: str
    description: str
    shipped: float
    domain_low: float
    domain_open: bool
    box: tuple[float, float]
    overrides: Callable[[float], dict[str, Any]]

    def check(self, variable: DesignVariable) -> None:
        """Refuse a box reaching outside the domain (``> low`` when open, else ``>= low``) or of zero width."""
        low, name = variable.low, self.name
        if low < self.domain_low or (self.domain_open and low == self.domain_low):
            raise ConfigError(f"{name}: lower bound must be {'>' if self.domain_open else '>='} "
                              f"{self.domain_low:g} {self.unit}, got {low:g}")
        if variable.high <= variable.low:
            raise ConfigError(f"{name}: upper bound must be > lower bound, got {variable.high:g} <= {variable.low:g}")


#: The plant's open assumptions, by name.
PARAMETERS: dict[str, PlantParameter] = {p.name: p for p in (
    PlantParameter("ke", "count/BLU", "encoder gain K_e", 1.0, 0.0, True, (0.2, 2.0), _ke),
    PlantParameter("lag_s", "s", "unmodelled lag added to each axis's tau", 0.0, 0.0, False, (0.0, 0.15), _lag),
    PlantParameter("friction_scale", "-", "factor on Eq. 15's friction", 1.0, 0.0, False, (0.0, 3.0),
                   _per_axis("friction_scale")),
    PlantParameter("saturation_dac", "DAC", "saturation of the drive input", 127.0, 0.0, True, (40.0, 127.0),
                   _per_axis("command_limit_dac")),
)}


def default_variables() -> tuple[DesignVariable, ...]:
    """Every parameter of :data:`PARAMETERS` over its default box."""
    return tuple(DesignVariable(p.name, *p.box) for p in PARAMETERS.values())


def check_variables(variables: Sequence[DesignVariable]) -> None:
    """Refuse an unknown parameter (listing the valid ones), a name given twice, or a bad box."""
    check_unique(variables)
    for variable in variables:
        require_choice("calibration parameter", variable.path, PARAMETERS)
        PARAMETERS[variable.path].check(variable)


def plant_overrides(variables: Sequence[DesignVariable], x: Sequence[float]) -> dict[str, Any]:
    """The scenario overrides that set each parameter to its value in ``x`` (same order as ``variables``)."""
    result: dict[str, Any] = {}
    for variable, value in zip(variables, x, strict=True):
        result = merge(result, PARAMETERS[variable.path].overrides(float(value)))
    return result


def shipped_point(variables: Sequence[DesignVariable]) -> tuple[float, ...]:
    """The shipped (uncalibrated) value of each parameter."""
    return tuple(PARAMETERS[v.path].shipped for v in variables)


# =========================================================================== runs
@dataclass(frozen=True)
class CaseRun:
    """One engine run: a Table 5 case with a controller, a plant seed and scenario overrides."""

    case: str
    controller: str
    seed: int
    overrides: Mapping[str, Any]


def _case_scenario(item: CaseRun) -> Scenario:
    row = next(r for r in TABLE5 if r.case == item.case)
    return scenario_for(project_root() / row.scenario, get_controller(item.controller), item.seed, item.overrides)


def run_case(item: CaseRun) -> tuple[float, float]:
    """(max, RMS) contour error [BLU] of one engine run, ``paper`` view, the project's scorer."""
    return blu(score_run(apply_view(run_engine(_case_scenario(item)), VIEWS["paper"]), ("max", "rms")))


def compare_case(item: CaseRun) -> CaseResult:
    """:func:`run_case`, or the fault that stopped the run (its axis, time and reason)."""
    scenario = _case_scenario(item)
    try:
        return blu(score_run(apply_view(run_engine(scenario), VIEWS["paper"]), ("max", "rms")))
    except CncError as err:  # a fault of the machine is a row of the comparison, not the bench's end
        return fault_row(err, scenario.plant.axes)


def pid_targets(rows: Sequence[Table5Row] = TABLE5) -> Figures:
    """Table 5's PID column [BLU] by (case, metric): the only paper numbers the fit sees."""
    return {(row.case, metric): row.paper_value("pid", metric) for row in rows for metric in ("max", "rms")}


# =========================================================================== the objective
@dataclass(frozen=True)
class PidColumnObjective:
    """RMS of ln(ours / paper) over the PID column's figures, our PID mean over ``fit_seeds`` (picklable)."""

    variables: tuple[DesignVariable, ...]
    targets: tuple[tuple[str, str, float], ...]
    fit_seeds: tuple[int, ...] = (1,)

    @classmethod
    def of(cls, variables: Sequence[DesignVariable], rows: Sequence[Table5Row] = TABLE5,
           fit_seeds: Sequence[int] = (1,)) -> PidColumnObjective:
        """The objective over ``rows``' PID column (checked variables)."""
        check_variables(variables)
        targets = tuple((case, metric, value) for (case, metric), value in pid_targets(rows).items())
        return cls(tuple(variables), targets, tuple(fit_seeds))

    def figures(self, x: Sequence[float] | np.ndarray) -> Figures:
        """Our PID's figures [BLU] at ``x``, mean over the fit seeds."""
        overrides = plant_overrides(self.variables, list(x))
        cases = sorted({case for case, _, _ in self.targets})
        runs = {(c, s): run_case(CaseRun(c, "pid", s, overrides)) for c in cases for s in self.fit_seeds}
        return {(c, m): statistics.fmean(runs[(c, s)][k] for s in self.fit_seeds)
                for c in cases for k, m in enumerate(("max", "rms"))}

    def residuals(self, x: Sequence[float] | np.ndarray) -> dict[tuple[str, str], float]:
        """ln(ours / paper) per (case, metric)."""
        ours = self.figures(x)
        return {(c, m): math.log(ours[(c, m)] / paper) for c, m, paper in self.targets}

    def __call__(self, x: np.ndarray) -> float:
        try:
            values = list(self.residuals(x).values())
        except (CncError, ValueError):
            return math.inf
        return math.sqrt(statistics.fmean(r * r for r in values))


# =========================================================================== the fit
@dataclass(frozen=True)
class Fit:
    """The optima of several DE seeds, best first."""

    objective: PidColumnObjective
    results: tuple[TuningResult, ...]
    seeds: tuple[int, ...]

    @property
    def best(self) -> TuningResult:
        """The lowest objective."""
        return self.results[0]

    def on_bounds(self, result: TuningResult) -> list[str]:
        """``name=low`` / ``name=high`` for each value within :data:`ON_BOUND_FRACTION` of a bound."""
        out = []
        for v, value in zip(self.objective.variables, result.x, strict=True):
            width = v.high - v.low
            out += [f"{v.path}={side}" for side, bound in (("low", v.low), ("high", v.high))
                    if abs(value - bound) <= ON_BOUND_FRACTION * width]
        return out


def fit(objective: PidColumnObjective, executor: Executor, *, seeds: Sequence[int] = (0, 1, 2),
        maxiter: int = 25, popsize: int = 8) -> Fit:
    """Minimise ``objective`` once per DE seed (each generation through ``executor``)."""
    if not seeds:
        raise ConfigError("fit seeds must name at least one DE seed, got none")
    results = [solve(objective, objective.variables, executor=executor, maxiter=maxiter, popsize=popsize,
                     seed=int(seed), unit="ln ratio") for seed in seeds]
    order = sorted(range(len(results)), key=lambda i: results[i].objective)
    return Fit(objective, tuple(results[i] for i in order), tuple(int(seeds[i]) for i in order))


def profile(objective: PidColumnObjective, x: Sequence[float], executor: Executor,
            step_fraction: float = 0.1) -> dict[str, tuple[float, float]]:
    """Objective with each parameter moved by ±``step_fraction`` of its box (clipped): flat means unidentified."""
    points, names = [], []
    for i, v in enumerate(objective.variables):
        for sign in (-1.0, 1.0):
            moved = list(x)
            moved[i] = float(np.clip(x[i] + sign * step_fraction * (v.high - v.low), v.low, v.high))
            points.append(np.asarray(moved))
        names.append(v.path)
    values = executor.map(objective, points, label="profile")
    return {name: (values[2 * k], values[2 * k + 1]) for k, name in enumerate(names)}


# =========================================================================== PID vs FLC
def compare(overrides: Mapping[str, Any], seeds: Sequence[int], executor: Executor,
            cases: Sequence[str] | None = None) -> dict[tuple[str, str], list[CaseResult]]:
    """(max, RMS) [BLU] or the fault, per seed, for every (case, ``pid``/``flc``) on the plant of ``overrides``."""
    names = list(cases) if cases is not None else [row.case for row in TABLE5]
    items = [CaseRun(c, law, s, dict(overrides)) for c in names for law in ("pid", "flc") for s in seeds]
    values = executor.map(compare_case, items, label="pid vs flc")
    out: dict[tuple[str, str], list[CaseResult]] = {}
    for item, value in zip(items, values, strict=True):
        out.setdefault((item.case, item.controller), []).append(value)
    return out


# =========================================================================== the bench
@dataclass(frozen=True)
class BenchPlan:
    """How much the bench runs: DE seeds, generations, population multiplier, plant seeds of the comparison."""

    fit_seeds: tuple[int, ...]
    maxiter: int
    popsize: int
    compare_seeds: tuple[int, ...]


#: ``--quick``: one DE seed, a tiny population, one plant seed.
QUICK = BenchPlan((0,), 3, 3, (1,))
#: The full bench: three DE seeds (identifiability), five plant seeds.
FULL = BenchPlan((0, 1, 2), 25, 8, (1, 2, 3, 4, 5))


def plan_of(options: argparse.Namespace) -> BenchPlan:
    """QUICK or FULL, the comparison's plant seeds 1..``--seeds`` when given."""
    plan = QUICK if getattr(options, "quick", False) else FULL
    count = getattr(options, "seeds", None)
    if count is None:
        return plan
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ConfigError(f"seeds must be an integer >= 1, got {count!r}")
    return BenchPlan(plan.fit_seeds, plan.maxiter, plan.popsize, tuple(range(1, count + 1)))


def _fit_table(result: Fit, shipped_value: float) -> str:
    names = [v.path for v in result.objective.variables]
    rows: list[list[object]] = [["shipped", "-", f"{shipped_value:.3f}",
                                 *(f"{x:g}" for x in shipped_point(result.objective.variables)), "-"]]
    rows += [[f"DE seed {seed}", r.evaluations, f"{r.objective:.3f}", *(f"{x:.4g}" for x in r.x),
              ", ".join(result.on_bounds(r)) or "none"] for seed, r in zip(result.seeds, result.results)]
    return format_table(["point", "evaluations", "RMS ln(ours/paper)", *names, "on a bound"], rows)


def _box_table(result: Fit, profiles: Mapping[str, tuple[float, float]]) -> str:
    rows = []
    for k, v in enumerate(result.objective.variables):
        found = [r.x[k] for r in result.results]
        p = PARAMETERS[v.path]
        rows.append([v.path, p.unit, p.description, f"{v.low:g}..{v.high:g}", f"{result.best.x[k]:.4g}",
                     f"{min(found):.4g}..{max(found):.4g}", "/".join(f"{x:.3f}" for x in profiles[v.path])])
    return format_table(["parameter", "unit", "what", "box", "best", "spread over DE seeds",
                         "objective at -/+10 % of box"], rows)


def _residual_table(objective: PidColumnObjective, shipped: Figures, calibrated: Figures) -> str:
    rows = [[case, metric, f"{paper:g}", f"{shipped[(case, metric)]:.2f}",
             f"{shipped[(case, metric)] / paper:.2f}", f"{calibrated[(case, metric)]:.2f}",
             f"{calibrated[(case, metric)] / paper:.2f}", f"{math.log(calibrated[(case, metric)] / paper):+.3f}"]
            for case, metric, paper in objective.targets]
    return format_table(["case", "metric", "paper PID", "shipped", "shipped/paper", "calibrated",
                         "calibrated/paper", "residual ln"], rows)


def _ran(results: Sequence[CaseResult], k: int) -> list[float]:
    return [v[k] for v in results if not isinstance(v, FaultRow)]


def _ratio(flc: Sequence[float], pid: Sequence[float]) -> str:
    return f"{statistics.fmean(flc) / statistics.fmean(pid):.2f}" if flc and pid else "—"


def _compare_rows(runs: Comparison, metric: str, rows_of: Sequence[Table5Row]) -> list[list[object]]:
    """Per case: each law's mean ± spread over the runs that finished, FLC <= PID over the seeds where both
    finished, and the faulted runs apart (never a win)."""
    k = 0 if metric == "max" else 1
    rows: list[list[object]] = []
    for row in rows_of:
        pid_all, flc_all = runs[(row.case, "pid")], runs[(row.case, "flc")]
        pid, flc = _ran(pid_all, k), _ran(flc_all, k)
        both = [(f[k], p[k]) for p, f in zip(pid_all, flc_all, strict=True)
                if not isinstance(p, FaultRow) and not isinstance(f, FaultRow)]
        paper_pid, paper_flc = row.paper_value("pid", metric), row.paper_value("flc", metric)
        faulted = [sum(isinstance(v, FaultRow) for v in found) for found in (pid_all, flc_all)]
        rows.append([row.case, stat_text(pid) if pid else "—", f"{paper_pid:g}", stat_text(flc) if flc else "—",
                     f"{paper_flc:g}", _ratio(flc, pid), f"{paper_flc / paper_pid:.2f}",
                     wins([f for f, _ in both], [p for _, p in both]), "/".join(map(str, faulted))])
    return rows


def fault_rows(runs: Comparison, seeds: Sequence[int]) -> list[list[object]]:
    """One row per faulted run: case, law, plant seed, ``faulted`` and the fault (axis, time, reason)."""
    return [[case, law, seed, "faulted", v.text] for (case, law), found in runs.items()
            for seed, v in zip(seeds, found, strict=True) if isinstance(v, FaultRow)]


def fits_fault_text(fits: Sequence[int], runs: Sequence[Comparison], seeds: Sequence[int]) -> str:
    """A row per faulted run of every fit's comparison (DE seed, case, law, plant seed, fault); "" when none."""
    rows = [[f"DE seed {fit_seed}", *row] for fit_seed, found in zip(fits, runs, strict=True)
            for row in fault_rows(found, seeds)]
    if not rows:
        return ""
    return (f"\nfaulted runs on the fitted plants ({len(rows)}; no figures, counted as a win for neither law):\n"
            + format_table(["fit", "case", "law", "plant seed", "result", "fault"], rows))


def compare_text(runs: Comparison, seeds: Sequence[int], rows_of: Sequence[Table5Row] = TABLE5,
                 with_faults: bool = True) -> str:
    """The PID vs FLC tables (max, RMS) and (``with_faults``) a row for each faulted run."""
    parts = []
    for metric in ("max", "rms"):
        parts.append(f"\n{metric} contour error [BLU], calibrated plant (best fit), plant seeds {list(seeds)}:")
        parts.append(format_table(["case", "PID ours", "PID paper", "FLC ours", "FLC paper", "FLC/PID ours",
                                   "FLC/PID paper", "FLC <= PID (seeds both ran)", "faulted PID/FLC"],
                                  _compare_rows(runs, metric, rows_of)))
    faults = fault_rows(runs, seeds)
    if faults and with_faults:
        parts.append(f"\nfaulted runs ({len(faults)}; no figures, counted as a win for neither law):")
        parts.append(format_table(["case", "law", "plant seed", "result", "fault"], faults))
    return "\n".join(parts)


def _ratio_line(runs: Comparison) -> list[str]:
    """FLC/PID of the means (runs that finished), max/RMS, per case; the faulted runs' count when any."""
    out = []
    for r in TABLE5:
        found = (runs[(r.case, "pid")], runs[(r.case, "flc")])
        faulted = sum(isinstance(v, FaultRow) for results in found for v in results)
        text = "/".join(_ratio(_ran(found[1], k), _ran(found[0], k)) for k in (0, 1))
        out.append(text + (f" ({faulted} faulted)" if faulted else ""))
    return out


def _print_report(result: Fit, figures: Sequence[Figures], profiles: Mapping[str, tuple[float, float]],
                  runs: Sequence[Comparison], plan: BenchPlan) -> None:
    """The fits, the parameters, the residuals (``figures``: shipped, best), PID vs FLC on every fit."""
    objective = result.objective
    print("\nfits (objective: RMS over the 12 PID figures of ln(ours/paper)):")
    print(_fit_table(result, objective(np.asarray(shipped_point(objective.variables)))))
    print("\nparameters:")
    print(_box_table(result, profiles))
    print("\nresiduals against Table 5's PID column, plant seed 1:")
    print(_residual_table(objective, figures[0], figures[1]))
    print(compare_text(runs[0], plan.compare_seeds, with_faults=False))  # every fit's faults: below
    print("\nFLC/PID of the means (max/RMS) on each DE seed's fitted plant (paper: "
          + ", ".join(f"{r.max_flc_blu / r.max_pid_blu:.2f}/{r.rms_flc_blu / r.rms_pid_blu:.2f}" for r in TABLE5)
          + "):")
    print(format_table(["fit", *(r.case for r in TABLE5)],
                       [[f"DE seed {s}", *_ratio_line(r)] for s, r in zip(result.seeds, runs)]))
    faults = fits_fault_text(result.seeds, runs, plan.compare_seeds)
    if faults:
        print(faults)


def paper000_calibrated_bench(options: argparse.Namespace) -> int:
    """Fit the plant to Table 5's PID column from several DE seeds, then PID vs FLC on each fitted plant."""
    started, plan = time.perf_counter(), plan_of(options)
    objective = PidColumnObjective.of(default_variables())
    print(f"paper000-calibrated: fit {[v.path for v in objective.variables]} to Table 5's PID column "
          f"(DE seeds {list(plan.fit_seeds)}, maxiter {plan.maxiter}, popsize {plan.popsize}), "
          f"then PID vs FLC, plant seeds {list(plan.compare_seeds)}, engine", flush=True)
    if plan == QUICK:
        print("--quick: a smoke run; its fit is not converged, read the full bench's tables", flush=True)
    with make_executor(getattr(options, "workers", None), getattr(options, "scheduler", None)) as executor:
        result = fit(objective, executor, seeds=plan.fit_seeds, maxiter=plan.maxiter, popsize=plan.popsize)
        figures = executor.map(objective.figures, [shipped_point(objective.variables), result.best.x],
                               label="figures")
        profiles = profile(objective, result.best.x, executor)
        runs = [compare(plant_overrides(objective.variables, r.x), plan.compare_seeds, executor)
                for r in result.results]
    _print_report(result, figures, profiles, runs, plan)
    wall_s = time.perf_counter() - started
    print(f"\nwall time: {wall_s:.1f} s")
    write_json(getattr(options, "json", None), {
        "bench": "paper000-calibrated", "machine": machine(), "wall_time_s": wall_s,
        "plan": asdict(plan), "profile": profiles,
        "fits": [{"de_seed": s, "x": r.values(), "objective": r.objective, "evaluations": r.evaluations,
                  "on_bounds": result.on_bounds(r)} for s, r in zip(result.seeds, result.results)],
        "compare": [{f"{c}/{law}": [asdict(x) if isinstance(x, FaultRow) else x for x in v]
                     for (c, law), v in r.items()} for r in runs]})
    return 0
