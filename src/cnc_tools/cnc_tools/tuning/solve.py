"""The tuner's solver: :func:`scipy.optimize.differential_evolution` with constraints, seeded, on an executor.

The population is evaluated through ``executor.map`` (DE's ``workers`` takes
any map-like callable; ``updating="deferred"`` then evaluates a whole
generation at once). Constraints are one :class:`~scipy.optimize.NonlinearConstraint`
whose components are the constraints' figures, bounded on one side. A problem
no point of the box can satisfy ends with ``feasible = False`` and the
smallest total violation seen, never an exception.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import Bounds, NonlinearConstraint, differential_evolution

from cnc_contour_control.core.config import require_positive
from cnc_contour_control.core.errors import ConfigError
from cnc_tools.runs.executor import Executor
from cnc_tools.runs.progress import Task
from cnc_tools.runs.progress import task as progress_task
from cnc_tools.tuning.problem import Constraint, DesignVariable, check_unique

#: Constraint values of a point, in the order of the constraints.
ConstraintFunction = Callable[[np.ndarray], Sequence[float]]


@dataclass(frozen=True)
class TuningResult:
    """What a tuning run found.

    Attributes
    ----------
    x : optimum, one value per design variable.
    objective : the objective at ``x`` (in ``unit``).
    constraint_values : each constraint's figure at ``x``.
    violation : the summed violation at ``x`` (0 when feasible).
    feasible : every constraint holds at ``x``.
    history : best objective after each generation (the convergence history).
    evaluations : objective evaluations made.
    message : the solver's message.
    """

    variables: tuple[DesignVariable, ...]
    constraints: tuple[Constraint, ...]
    x: tuple[float, ...]
    objective: float
    constraint_values: tuple[float, ...]
    violation: float
    feasible: bool
    history: tuple[float, ...]
    evaluations: int
    message: str
    unit: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def values(self) -> dict[str, float]:
        """The optimum by variable path."""
        return {v.path: value for v, value in zip(self.variables, self.x, strict=True)}


def _violation(constraints: Sequence[Constraint], values: Sequence[float]) -> float:
    return float(sum(c.violation(v) for c, v in zip(constraints, values, strict=True)))


def _nonlinear(constraints: Sequence[Constraint], values_of: ConstraintFunction) -> list[NonlinearConstraint]:
    """One NonlinearConstraint holding every constraint as a one-sided bound."""
    if not constraints:
        return []
    low = [c.bound if c.op == ">=" else -np.inf for c in constraints]
    high = [c.bound if c.op == "<=" else np.inf for c in constraints]
    return [NonlinearConstraint(lambda x: np.asarray(values_of(x), dtype=float), low, high)]


@dataclass
class _Tracker:
    """Keeps the best objective of each generation (DE's callback) and shows it as a step of ``generations``:
    the best and whether it meets the constraints (DE's ``maxcv``, its largest violation, when it has some)."""

    history: list[float] = field(default_factory=list)
    generations: Task | None = None
    unit: str = ""

    def __call__(self, intermediate_result: Any) -> None:
        self.history.append(float(intermediate_result.fun))
        if self.generations is not None:
            self.generations.step(note=self.note(self.history[-1], getattr(intermediate_result, "maxcv", None)))

    def note(self, best: float, violation: float | None) -> str:
        """The generation's best and its constraints: met, or the largest violation (None: no constraints)."""
        if violation is not None and violation > 0 and not np.isfinite(best):
            return f"no member meets the constraints, least violation {violation:.3g}"
        text = f"best {best:.6g}{' ' + self.unit if self.unit else ''}"
        if violation is None:
            return text
        return text + (", meets the constraints" if violation <= 0 else f", violates a constraint by {violation:.3g}")


def solve(objective: Callable[[np.ndarray], float], variables: Sequence[DesignVariable],
          constraints: Sequence[Constraint] = (), values_of: ConstraintFunction | None = None, *,
          executor: Executor | None = None, maxiter: int = 30, popsize: int = 8, seed: int = 0,
          unit: str = "") -> TuningResult:
    """Minimise ``objective`` over the variables' box subject to ``constraints`` (figures from ``values_of``).

    Parameters
    ----------
    objective
        Picklable function of x (n,) -> float.
    variables, constraints
        The box and the constraints; ``values_of(x)`` gives the constraints' figures in order.
    executor
        Evaluates each generation (``executor.map``); None: in this process.
    maxiter, popsize, seed
        DE's generations, population multiplier (``popsize * n`` members) and seed.
    """
    check_unique(variables)
    require_positive("maxiter", maxiter, "tune")
    require_positive("popsize", popsize, "tune")
    if constraints and values_of is None:
        raise ConfigError("constraints given without a function of their values (values_of)")
    values = values_of or (lambda x: [])
    workers: Any = 1 if executor is None else (lambda fn, xs: executor.map(fn, list(xs), label="tune"))
    box = Bounds([v.low for v in variables], [v.high for v in variables])
    with progress_task("tune generation", int(maxiter)) as generations:  # DE may converge before maxiter
        tracker = _Tracker(generations=generations, unit=unit)
        found = differential_evolution(objective, box, constraints=_nonlinear(constraints, values), seed=seed,
                                       maxiter=int(maxiter), popsize=int(popsize), polish=False,
                                       updating="deferred", workers=workers, callback=tracker, tol=1e-8)
    return _result(found, variables, constraints, values, tracker, unit)


def _result(found: Any, variables: Sequence[DesignVariable], constraints: Sequence[Constraint],
            values_of: ConstraintFunction, tracker: _Tracker, unit: str) -> TuningResult:
    """The result at DE's answer: with constraints, DE prefers any feasible member, then the least violating."""
    x = np.asarray(found.x, dtype=float)
    figures = [float(f) for f in values_of(x)] if constraints else []
    violation = _violation(constraints, figures) if constraints else 0.0
    return TuningResult(tuple(variables), tuple(constraints), tuple(float(v) for v in x), float(found.fun),
                        tuple(figures), violation, violation == 0.0, tuple(tracker.history), int(found.nfev),
                        str(found.message), unit)
