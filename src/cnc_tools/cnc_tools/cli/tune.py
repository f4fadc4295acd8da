"""``cnc-contour tune SCENARIO --var PATH=LO:HI ...``: choose scenario parameters by differential evolution.

Objective ``analytic`` (paper 003's Eq. 17 over its grid) or ``circular``
(simulated CW + CCW circular tests scored by the ballbar diagnosis), optional
constraints on the paper-003 linear model (``--constraint phase_margin_deg>=45``),
population evaluated on a local pool (``--workers``) or a Dask cluster
(``--scheduler``). Writes result.json, convergence.png and the tuned scenario
to ``--out``. See ``docs/tuning.md``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from cnc_contour_control.core.errors import CncError
from cnc_tools.cli.common import parse_overrides
from cnc_tools.runs.executor import Executor, make_executor
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.scenario import Scenario, load_scenario
from cnc_tools.tuning import paper003_model as p3
from cnc_tools.tuning.objectives import (
    CIRCLE_FIGURES,
    CONSTRAINT_FIGURES,
    OBJECTIVES,
    check_constraints,
    constraint_values,
    make_objective,
    model_at,
)
from cnc_tools.tuning.output import result_table, write_outputs
from cnc_tools.tuning.problem import Constraint, DesignVariable, check_unique, parse_constraint, parse_variable
from cnc_tools.tuning.solve import ConstraintFunction, solve

#: Exit code when no point of the box meets the constraints (errors exit 2).
INFEASIBLE_EXIT = 3


def configure(parser: argparse.ArgumentParser) -> None:
    """Options of ``cnc-contour tune``."""
    parser.add_argument("scenario", type=Path, help="scenario YAML file")
    parser.add_argument("--var", dest="variables", action="append", default=[], metavar="PATH=LO:HI",
                        help="design variable: a scenario key and its bounds, e.g. servo.law_params.kp=0.5:8")
    parser.add_argument("--objective", default="analytic", choices=sorted(OBJECTIVES),
                        help="analytic (paper 003 Eq. 17) or circular (simulated CW + CCW circles)")
    parser.add_argument("--figure", default="max_radial_deviation_um", choices=sorted(CIRCLE_FIGURES),
                        help="what the circular objective minimises")
    parser.add_argument("--lag", default="envelope", choices=sorted(p3.LAG_READINGS),
                        help="analytic objective: which lag T(K1, K2) Eq. 12 means")
    parser.add_argument("--lag-form", default="eq12_peak", choices=sorted(p3.LAG_FORMS),
                        help="analytic objective: how the lag becomes a radius error")
    parser.add_argument("--interpolation", default="exponential", choices=sorted(p3.INTERPOLATIONS),
                        help="analytic objective: Eq. 13's acceleration/deceleration kind")
    parser.add_argument("--aggregate", default="mean", choices=sorted(p3.AGGREGATES),
                        help="analytic objective: how the grid's 24 circles become one figure")
    parser.add_argument("--constraint", dest="constraints", action="append", default=[], metavar="NAME>=BOUND",
                        help=f"constraint on the paper-003 linear model; figures {sorted(CONSTRAINT_FIGURES)}")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario key before tuning")
    parser.add_argument("--workers", type=int, help="processes evaluating the population (default all cores)")
    parser.add_argument("--scheduler", help="Dask scheduler tcp://host:port (instead of the local pool)")
    parser.add_argument("--maxiter", type=int, default=30, help="generations (default 30)")
    parser.add_argument("--popsize", type=int, default=8, help="population = popsize x variables (default 8)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the search (default 0)")
    parser.add_argument("--out", type=Path, help="output folder (default bags/tune/<scenario>/<timestamp>)")


def _constraint_function(scenario: Scenario, variables: tuple[DesignVariable, ...],
                         constraints: tuple[Constraint, ...]) -> ConstraintFunction:
    """x -> the constraints' figures at the paper-003 model of the scenario with x set."""
    return lambda x: constraint_values(model_at(scenario.raw, variables, x), constraints)


def _executor(workers: int | None, scheduler: str | None) -> Executor:
    """The executor; an unreachable scheduler is a CncError naming it (the client times out after 30 s)."""
    try:
        return make_executor(workers, scheduler)
    except OSError as err:
        raise CncError(f"--scheduler {scheduler}: cannot reach the Dask scheduler: {err}") from err


def tune(args: argparse.Namespace) -> int:
    """Parse the problem, solve it, print and write the result; exit 3 when no point meets the constraints."""
    scenario = load_scenario(args.scenario, parse_overrides(args.overrides))
    variables = tuple(parse_variable(text) for text in args.variables)
    check_unique(variables)
    constraints = tuple(parse_constraint(text) for text in args.constraints)
    check_constraints(constraints, scenario, args.objective)
    readings = p3.Readings(lag=args.lag, lag_form=args.lag_form, interpolation=args.interpolation,
                           aggregate=args.aggregate)
    options = {"readings": readings, "figure": args.figure}
    objective = make_objective(args.objective, scenario, variables, options)
    workers = 1 if args.objective == "analytic" and args.scheduler is None and args.workers is None else args.workers
    print(f"tuning {scenario.name}: {len(variables)} variables, objective {args.objective}, "
          f"{len(constraints)} constraints, maxiter {args.maxiter}, seed {args.seed}", flush=True)
    with _executor(workers, args.scheduler) as executor:
        result = solve(objective, variables, constraints, _constraint_function(scenario, variables, constraints),
                       executor=executor, maxiter=args.maxiter, popsize=args.popsize, seed=args.seed,
                       unit=objective.unit)
    print(result_table(result))
    out_dir = args.out or project_root() / "bags" / "tune" / scenario.name / timestamp()
    for what, path in write_outputs(scenario, result, out_dir).items():
        print(f"{what + ':':<10}{path}")
    return 0 if result.feasible else INFEASIBLE_EXIT
