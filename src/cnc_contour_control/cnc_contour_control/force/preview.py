"""Preview from the part program: the override plan around each known depth step (ROS-free).

Feedback alone cannot beat the floor of a depth step (the force rises through
the τ_c lag while the feed falls only through τ_s). Knowing the step ahead,
the override can fall *before* it. Around each step of a
:class:`~cnc_contour_control.core.force_model.DepthSchedule` the plan chooses the
override ratios ``r_j`` (one per update period, held) that minimise the
largest force error on the model (Eqs. 1-4)::

    F = F_free + M r           M[i, j]: force at fine sample i from a unit ratio held in period j
    minimise w z_over + z_under + μ mean|F_i − F_ref|   subject to  −z_under <= F_i − F_ref <= z_over,
                                                        r_j in the switch's range (on its levels if quantised)

a linear program (``scipy.optimize.linprog``). With a quantised switch the
plan is rounded to the levels by error feedback (:func:`sigma_delta`: each
rounding error is carried into the next period, so the lags, which integrate,
see the continuous plan to within half a level held one period); on the
paper's steps this costs under 1 N against the continuous plan, where plain
rounding costs up to 28 N, and it is deterministic where a mixed-integer
program under a time limit is not. The
chain is linear in r though time-varying in d(t), so M is built by stepping
the model's :class:`FirstOrderLag` on a unit pulse per column at once. The
weight w (``overshoot_weight``) buys overshoot with undershoot: a dip costs
time, a peak breaks tools. The regulator (:mod:`.regulator`) applies a plan
inside its window and hands back to the feedback law at its end.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.force_model import DepthSchedule, FirstOrderLag, TurningModelConfig
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.force.quantiser import Quantiser, QuantiserConfig


@dataclass(frozen=True)
class PreviewConfig:
    """The planning window around each depth step.

    Parameters
    ----------
    before_s, after_s : float
        Window before and after the step [s], in [0, 5].
    sample_s : float
        Fine sample of the force constraints [s], in [1e-4, 0.1].
    overshoot_weight : float
        Cost of the largest overshoot against the largest undershoot, in [0, 1e6].
    mean_weight : float
        Cost of the mean absolute force error (keeps the force near the reference where the extremes
        do not bind), in [0, 1e6].
    """

    before_s: float = param(0.3, unit="s", low=0.0, high=5.0, description="plan window before a depth step")
    after_s: float = param(0.5, unit="s", low=0.0, high=5.0, description="plan window after a depth step")
    sample_s: float = param(2.0e-3, unit="s", low=1.0e-4, high=0.1, description="force constraint sample")
    overshoot_weight: float = param(10.0, low=0.0, high=1.0e6, description="cost of overshoot against undershoot")
    mean_weight: float = param(1.0, low=0.0, high=1.0e6, description="cost of the mean absolute error")

    def __post_init__(self) -> None:
        check_ranges(self, "preview")


@dataclass(frozen=True)
class StepPlan:
    """The plan of one depth step: ratios held from ``start_s`` every ``period_s``; the model's worst errors [N];
    the depth after the step and the model's steady ratio there (where the feedback law restarts)."""

    start_s: float
    period_s: float
    ratios: npt.NDArray[np.float64]
    overshoot_n: float
    undershoot_n: float
    depth_after_mm: float
    ratio_after: float

    @property
    def end_s(self) -> float:
        """End of the window [s]."""
        return self.start_s + self.period_s * len(self.ratios)

    def ratio_at(self, t_s: float) -> float | None:
        """The planned ratio at ``t_s`` [s], None outside the window."""
        j = int(np.floor((t_s - self.start_s) / self.period_s + 1e-9))
        return float(self.ratios[j]) if 0 <= j < len(self.ratios) else None


def _response(model: TurningModelConfig, depth_of: npt.NDArray[np.float64], columns: int, hold: int,
              start: tuple[float, float], dt_s: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Free response (from steady feed ``start[0]`` [mm/rev], force ``start[1]`` [N]) and M, on the fine samples."""
    n = len(depth_of)
    feed_lag = FirstOrderLag(model.interpolator_tau_s, start[0])
    chip_lag = FirstOrderLag(model.chip_tau_s, start[1])
    unit_feed, unit_chip = FirstOrderLag(model.interpolator_tau_s), FirstOrderLag(model.chip_tau_s)
    # one lag per column: FirstOrderLag's arithmetic runs elementwise on arrays as on floats
    unit_feed.value, unit_chip.value = np.zeros(columns), np.zeros(columns)  # type: ignore[assignment]  # see above
    free, matrix = np.empty(n), np.empty((n, columns))
    for i in range(n):
        pulse = np.zeros(columns)
        pulse[min(i // hold, columns - 1)] = model.programmed_feed_mm_rev
        gain = model.specific_force_n_mm2 * depth_of[i]
        free[i] = chip_lag.step(dt_s, gain * feed_lag.step(dt_s, 0.0))
        matrix[i] = unit_chip.step(dt_s, gain * unit_feed.step(dt_s, pulse))  # type: ignore[arg-type]  # elementwise
    return free, matrix


def _constraints(scaled: npt.NDArray[np.float64], error: npt.NDArray[np.float64]) -> tuple[np.ndarray, np.ndarray]:
    """``A x <= b`` over x = (levels, z_over, z_under, e_1..e_n): the error F − F_ref = ``error`` + scaled·levels."""
    n, columns = scaled.shape
    zeros, ones, eye = np.zeros((n, 1)), np.ones((n, 1)), np.eye(n)
    blank = np.zeros((n, n))
    a = np.vstack([np.hstack([scaled, -ones, zeros, blank]), np.hstack([-scaled, zeros, -ones, blank]),
                   np.hstack([scaled, zeros, zeros, -eye]), np.hstack([-scaled, zeros, zeros, -eye])])
    return a, np.concatenate([-error, error, -error, error])


def _solve(free: npt.NDArray[np.float64], matrix: npt.NDArray[np.float64], reference_n: float,
           switch: QuantiserConfig, config: PreviewConfig) -> npt.NDArray[np.float64]:
    """The continuous plan: weighted minimax plus the mean absolute error (x = ratios, z_over, z_under, |e_i|)."""
    from scipy.optimize import linprog
    n, columns = matrix.shape
    a, b = _constraints(matrix, free - reference_n)
    cost = np.r_[np.zeros(columns), config.overshoot_weight, 1.0, np.full(n, config.mean_weight / n)]
    bounds = [(switch.min_ratio, switch.max_ratio)] * columns + [(0.0, None)] * (n + 2)
    result = linprog(cost, A_ub=a, b_ub=b, bounds=bounds, method="highs")
    if result.x is None:
        raise ConfigError(f"preview: no plan found ({result.message})")
    return np.asarray(result.x[:columns], dtype=float)


def sigma_delta(ratios: npt.NDArray[np.float64], switch: QuantiserConfig) -> npt.NDArray[np.float64]:
    """``ratios`` (shape (m,)) on the switch's levels, each rounding error carried into the next value."""
    quantise, carried, out = Quantiser(switch), 0.0, np.empty(len(ratios))
    for j, ratio in enumerate(ratios):
        wanted = ratio + carried
        out[j] = quantise(wanted)
        carried = wanted - out[j]
    return out


def _errors(error_n: npt.NDArray[np.float64]) -> tuple[float, float]:
    """Largest overshoot and undershoot [N] of a force error series (0 when none)."""
    return max(float(error_n.max()), 0.0), max(float(-error_n.min()), 0.0)


def plan_step(model: TurningModelConfig, schedule: DepthSchedule, step_s: float, reference_n: float,
              period_s: float, switch: QuantiserConfig, config: PreviewConfig = PreviewConfig()) -> StepPlan:
    """The plan around the depth step at ``step_s`` [s], steady at ``reference_n`` before its window."""
    start_s = step_s - config.before_s
    hold = max(1, int(round(period_s / config.sample_s)))
    dt_s = period_s / hold
    columns = max(1, int(round((config.before_s + config.after_s) / period_s)))
    times = start_s + dt_s * np.arange(1, columns * hold + 1)
    depth_of = np.array([schedule.depth_mm(t - dt_s) for t in times])
    feed0 = model.steady_ratio(reference_n, schedule.depth_mm(start_s)) * model.programmed_feed_mm_rev
    free, matrix = _response(model, depth_of, columns, hold, (feed0, reference_n), dt_s)
    ratios = _solve(free, matrix, reference_n, switch, config)
    if switch.step_ratio > 0.0:
        ratios = sigma_delta(ratios, switch)
    over, under = _errors(free + matrix @ ratios - reference_n)
    depth_after = schedule.depth_mm(step_s)
    return StepPlan(start_s, period_s, ratios, over, under, depth_after, model.steady_ratio(reference_n, depth_after))


def plan_schedule(model: TurningModelConfig, schedule: DepthSchedule, reference_n: float, period_s: float,
                  switch: QuantiserConfig, config: PreviewConfig = PreviewConfig()) -> tuple[StepPlan, ...]:
    """One :func:`plan_step` per depth change of ``schedule`` to a depth > 0, in time order, windows apart.

    A step inside an earlier plan's window is in that plan already (its model runs the schedule through
    the whole window) and gets none; a step whose window would open inside an earlier one opens it at that
    window's end (a shorter lead). So the plans never overlap and a schedule of many close steps costs one
    linear program per window, not one per step.
    """
    plans: list[StepPlan] = []
    for t in schedule.step_times_s():
        end_s = plans[-1].end_s if plans else -math.inf
        if schedule.depth_mm(t) <= 0.0 or t < end_s - 1e-9:
            continue
        lead_s = min(config.before_s, max(t - end_s, 0.0))
        window = config if lead_s == config.before_s else dataclasses.replace(config, before_s=lead_s)
        plans.append(plan_step(model, schedule, t, reference_n, period_s, switch, window))
    return tuple(plans)
