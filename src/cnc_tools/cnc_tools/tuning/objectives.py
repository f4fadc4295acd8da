"""What the tuner minimises and what it constrains, each from a registry keyed by name.

Objectives (:data:`OBJECTIVES`), called on a point ``x`` (the design variables' values, in order):

- ``analytic``: paper 003's Eq. 17 over the paper's grid (:mod:`cnc_tools.tuning.paper003_model`)
  under one :class:`Readings`; the variables must be paths of :data:`ANALYTIC_PATHS`.
- ``circular``: a CW and a CCW run of the scenario's circle through :func:`run_engine`,
  diagnosed by :func:`diagnose_circles` and scored by a figure of :data:`CIRCLE_FIGURES` [µm].

Both are plain picklable objects, so a population is evaluated through an
executor (a process pool or a Dask cluster). Constraint figures
(:data:`CONSTRAINT_FIGURES`) come from the paper-003 linear model of the point
(its velocity loop, position gain and one-sample delay), read from the
scenario's keys through :data:`ANALYTIC_PATHS`.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from cnc_contour_control.core.config import require_choice
from cnc_contour_control.core.errors import CncError, ConfigError
from cnc_tools.analysis.ballbar import BallbarDiagnosis, diagnose_circles
from cnc_tools.analysis.ballbar_trace import trace_of
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import Scenario
from cnc_tools.tuning import paper003_model as p3
from cnc_tools.tuning.problem import Constraint, DesignVariable, lookup, overrides_of

#: Scenario key -> fields of :class:`Paper003Model` it sets: the paper-003 plant's keys
#: (``cnc_plant_sim.models.velocity_loop``: per axis ``ki`` = K1, ``kp`` = K2; the servo's ``p`` law's ``kp`` = k).
ANALYTIC_PATHS: dict[str, tuple[str, ...]] = {
    **{f"plant.axis_overrides.{axis}.ki": ("k1",) for axis in ("*", "x", "y")},
    **{f"plant.axis_overrides.{axis}.kp": ("k2",) for axis in ("*", "x", "y")},
    **{f"plant.axis_overrides.{axis}.torque_per_inertia": ("torque_per_inertia",) for axis in ("*", "x", "y")},
    "servo.law_params.kp": ("position_gain_x_1_s", "position_gain_y_1_s"),
    "servo.axes.x.law_params.kp": ("position_gain_x_1_s",),
    "servo.axes.y.law_params.kp": ("position_gain_y_1_s",),
    "interpolator.accel_decel.time_constant_s": ("t_ip_s",),
    "sample_time_s": ("sample_time_s",),
}


def model_at(raw: Mapping[str, Any], variables: Sequence[DesignVariable],
             x: Sequence[float] | np.ndarray) -> p3.Paper003Model:
    """The paper-003 model of a scenario mapping with the variables set to ``x`` (missing keys: model defaults).

    Only a ``paper003`` plant's keys are read from ``raw``; another plant's
    (e.g. paper 000's PID ``kp``) mean something else and are left out.
    """
    values: dict[str, float] = {}
    own = lookup(raw, "plant.model") == "paper003"
    for path, fields in (ANALYTIC_PATHS.items() if own else ()):
        found = lookup(raw, path)
        if isinstance(found, (int, float)) and not isinstance(found, bool):
            values.update({name: float(found) for name in fields})
    for variable, value in zip(variables, x, strict=True):
        values.update({name: float(value) for name in ANALYTIC_PATHS.get(variable.path, ())})
    return p3.Paper003Model(**values)


def _margin(index: int) -> Callable[[p3.Paper003Model], float]:
    return lambda model: p3.margins(model)[index]


#: Constraint figures of the linear model: name -> f(model).
CONSTRAINT_FIGURES: dict[str, Callable[[p3.Paper003Model], float]] = {
    "phase_margin_deg": _margin(0),
    "gain_margin_db": _margin(1),
    "phase_margin_eq15_deg": lambda m: p3.phase_margin_eq15_deg(m.zeta),
    "resonance_peak_db": p3.closed_resonance_peak_db,
    "rise_time_s": p3.rise_time_position_loop_s,
    "velocity_rise_time_s": p3.rise_time_velocity_loop_s,
}


def constraint_values(model: p3.Paper003Model, constraints: Sequence[Constraint]) -> list[float]:
    """Each constraint's figure at ``model`` (the margins computed once)."""
    cache: dict[str, float] = {}
    for constraint in constraints:
        if constraint.figure not in cache:
            if constraint.figure in ("phase_margin_deg", "gain_margin_db"):
                cache["phase_margin_deg"], cache["gain_margin_db"] = p3.margins(model)
            else:
                cache[constraint.figure] = CONSTRAINT_FIGURES[constraint.figure](model)
    return [cache[c.figure] for c in constraints]


def check_constraints(constraints: Sequence[Constraint], scenario: Scenario, objective: str) -> None:
    """Refuse unknown figures, and constraints on a simulated plant without the paper-003 linear model."""
    for constraint in constraints:
        require_choice("constraint", constraint.figure, CONSTRAINT_FIGURES)
    if constraints and objective != "analytic" and scenario.plant.model != "paper003":
        raise ConfigError(f"constraint {constraints[0]}: the constraint figures come from the paper003 linear model, "
                          f"but scenario.plant.model is {scenario.plant.model!r}; use a paper003 scenario "
                          "or the analytic objective")


class Objective(Protocol):
    """A picklable function of the design variables' values, with its unit."""

    @property
    def unit(self) -> str: ...  # read-only: a frozen dataclass's field satisfies it

    def __call__(self, x: np.ndarray) -> float: ...


@dataclass(frozen=True)
class AnalyticObjective:
    """Eq. 17 over the paper's grid [µm] at the scenario's paper-003 model with the variables set."""

    raw: Mapping[str, Any]
    variables: tuple[DesignVariable, ...]
    readings: p3.Readings = field(default_factory=p3.Readings)
    unit: str = "um"

    def __post_init__(self) -> None:
        for variable in self.variables:
            if variable.path not in ANALYTIC_PATHS:
                raise ConfigError(f"design variable {variable.path} names no parameter of the analytic model; "
                                  f"valid paths are {sorted(ANALYTIC_PATHS)}")

    def __call__(self, x: np.ndarray) -> float:
        try:
            return p3.objective_um(model_at(self.raw, self.variables, x), self.readings)
        except ConfigError:
            return math.inf  # a point the model refuses (e.g. K1 = 0) is no candidate


def _max_radial_deviation_um(diagnosis: BallbarDiagnosis) -> float:
    return max(abs(diagnosis.radial_deviation_max_um), abs(diagnosis.radial_deviation_min_um))


#: Figures of a CW + CCW diagnosis the circular objective can minimise [µm].
CIRCLE_FIGURES: dict[str, Callable[[BallbarDiagnosis], float]] = {
    "max_radial_deviation_um": _max_radial_deviation_um,
    "radius_reduction_um": lambda d: max(0.0, -d.radial_deviation_min_um),
    "circularity_ls_um": lambda d: d.circularity_ls_um,
}


def circle_diagnosis(scenario: Scenario) -> BallbarDiagnosis:
    """Run the scenario's circle CW and CCW on the engine and diagnose the pair."""
    traces = []
    for direction in ("cw", "ccw"):
        run = scenario.variant({"program": {"direction": direction}})
        traces.append(trace_of(Path(f"{scenario.name}[{direction}]"), run_engine(run)).trace)
    return diagnose_circles(traces)


@dataclass(frozen=True)
class CircularObjective:
    """A CW + CCW simulated circular test of the scenario with the variables set, scored by ``figure`` [µm]."""

    scenario: Scenario
    variables: tuple[DesignVariable, ...]
    figure: str = "max_radial_deviation_um"
    unit: str = "um"

    def __post_init__(self) -> None:
        require_choice("figure", self.figure, CIRCLE_FIGURES)
        if self.scenario.raw.get("program", {}).get("shape") != "circle":
            raise ConfigError(f"the circular objective needs a scenario whose program.shape is circle, "
                              f"got {self.scenario.raw.get('program', {}).get('shape')!r}")
        for variable in self.variables:
            for bound in (variable.low, variable.high):
                self.at((bound,), (variable,))

    def at(self, x: Sequence[float] | np.ndarray, variables: Sequence[DesignVariable] | None = None) -> Scenario:
        """The scenario with the variables set to ``x``; ConfigError names the variable that no key takes."""
        chosen = tuple(variables or self.variables)
        try:
            return self.scenario.variant(overrides_of(chosen, list(x), self.scenario.axes))
        except ConfigError as err:
            names = ", ".join(v.path for v in chosen)
            raise ConfigError(f"design variable {names}: the scenario does not take it: {err}") from err

    def __call__(self, x: np.ndarray) -> float:
        try:
            return CIRCLE_FIGURES[self.figure](circle_diagnosis(self.at(x)))
        except CncError:
            return math.inf


#: Objective builders by name: (scenario, variables, options) -> objective.
OBJECTIVES: dict[str, Callable[[Scenario, tuple[DesignVariable, ...], Mapping[str, Any]], Objective]] = {
    "analytic": lambda s, v, o: AnalyticObjective(s.raw, v, o.get("readings", p3.Readings())),
    "circular": lambda s, v, o: CircularObjective(s, v, o.get("figure", "max_radial_deviation_um")),
}


def make_objective(name: str, scenario: Scenario, variables: Sequence[DesignVariable],
                   options: Mapping[str, Any] | None = None) -> Objective:
    """The objective called ``name``; an unknown name lists the valid ones."""
    require_choice("objective", name, OBJECTIVES)
    return OBJECTIVES[name](scenario, tuple(variables), options or {})
