"""Issue 11's two goals for paper 003, and the readings of the paper's 135 -> 90 µm on the simulated loop.

- Goal (1), :func:`tune_on_grid`: K1, K2, the position gain k and the velocity
  feedforward ff1 (:data:`~cnc_tools.reproductions.paper003.runs.SETTING_VARIABLES`)
  tuned by the tuner's DE (:func:`cnc_tools.tuning.solve.solve`) on the simulated
  circular tests of a set of grid circles (:class:`~cnc_tools.reproductions.paper003.runs.GridObjective`:
  mean of the largest |radial deviation| of each measured turn), subject to
  phase margin >= 45° and gain margin >= 6 dB of the paper-003 linear position
  loop with one sample of delay (the tuner's constraint figures; ff1 is outside
  the loop and does not change them).
- Goal (2), :func:`analytic_optima`: the analytic objective's optimum per lag
  reading and box (the tuner's :func:`~cnc_tools.tuning.paper003_readings.box_rows`).
- :func:`gain_for_mean_um`: the position gain at which the linear prediction of
  the standard column's grid mean is the paper's 135 µm (one number fitted to
  one; the optimal column at that gain is then a prediction).
"""
from __future__ import annotations

import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import brentq

from cnc_tools.reproductions.paper003 import data
from cnc_tools.reproductions.paper003.runs import (
    SETTING_VARIABLES,
    GridCircle,
    GridObjective,
    Setting,
    predicted_reduction_um,
    setting_at,
)
from cnc_tools.runs.executor import Executor
from cnc_tools.runs.scenario import Scenario
from cnc_tools.tuning import paper003_model as p3
from cnc_tools.tuning.objectives import constraint_values, model_at
from cnc_tools.tuning.paper003_readings import box_rows
from cnc_tools.tuning.problem import Constraint
from cnc_tools.tuning.solve import TuningResult, solve

#: Goal (1)'s constraints: phase and gain margin of the delayed position loop.
GOAL_CONSTRAINTS: tuple[Constraint, ...] = (Constraint("phase_margin_deg", ">=", 45.0),
                                           Constraint("gain_margin_db", ">=", 6.0))
#: Search range of the position gain when fitting the grid mean to the paper's value [1/s].
GAIN_SEARCH_1_S = (1.0, 1000.0)


@contextmanager
def _quiet_margins() -> Iterator[None]:
    """python-control divides by zero evaluating a loop with an integrator at ω = 0; the margins handle it."""
    with warnings.catch_warnings(), np.errstate(divide="ignore", invalid="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


@dataclass(frozen=True)
class SearchPlan:
    """How long goal (1)'s DE searches: generations, population multiplier, seed."""

    maxiter: int
    popsize: int
    seed: int = 1


def margins_of(base: Scenario, setting: Setting) -> dict[str, float]:
    """The goal's constraint figures (and the resonance peak) of a setting's linear model."""
    x = (setting.k1, setting.k2, setting.position_gain_1_s, setting.ff1)
    model = model_at(base.raw, SETTING_VARIABLES, x)
    figures = (*GOAL_CONSTRAINTS, Constraint("resonance_peak_db", "<=", 0.0))
    with _quiet_margins():
        values = constraint_values(model, figures)
    return {c.figure: v for c, v in zip(figures, values, strict=True)}


def tune_on_grid(base: Scenario, circles: Sequence[GridCircle], plan: SearchPlan,
                 executor: Executor | None) -> tuple[Setting, TuningResult]:
    """Goal (1): DE over :data:`SETTING_VARIABLES` on the simulated circles, the margins constrained."""
    objective = GridObjective(base, tuple(circles))

    def values_of(x: np.ndarray) -> list[float]:
        with _quiet_margins():
            return constraint_values(model_at(base.raw, SETTING_VARIABLES, x), GOAL_CONSTRAINTS)

    result = solve(objective, SETTING_VARIABLES, GOAL_CONSTRAINTS, values_of, executor=executor,
                   maxiter=plan.maxiter, popsize=plan.popsize, seed=plan.seed, unit="um")
    return setting_at("tuned", result.x), result


def analytic_optima(maxiter: int, seed: int = 1) -> list[dict[str, Any]]:
    """Goal (2): the analytic optimum per lag reading in the box K1 <= 100, K2 <= 2.6 and ten times it."""
    return box_rows(maxiter=maxiter, seed=seed)


def predicted_mean_um(model: p3.Paper003Model, circles: Sequence[GridCircle]) -> float:
    """Mean over ``circles`` of the linear prediction of the radius reduction (no feedforward) [µm]."""
    return float(np.mean([predicted_reduction_um(model, 0.0, c) for c in circles]))


def gain_for_mean_um(model: p3.Paper003Model, circles: Sequence[GridCircle],
                     target_um: float = data.PAPER003_TABLE["standard"].radius_error_um) -> float | None:
    """The position gain k [1/s] at which the standard column's predicted grid mean is ``target_um``.

    None when no k in :data:`GAIN_SEARCH_1_S` reaches it (T_ip's own radius loss can exceed it).
    """
    def gap(gain_1_s: float) -> float:
        return predicted_mean_um(model.with_(position_gain_x_1_s=gain_1_s, position_gain_y_1_s=gain_1_s),
                                 circles) - target_um

    low, high = GAIN_SEARCH_1_S
    if gap(low) * gap(high) > 0.0:
        return None
    return float(brentq(gap, low, high, xtol=1e-6))
