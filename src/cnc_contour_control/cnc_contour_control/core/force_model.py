"""The turning process of paper 004 (Eqs. 1-5) as the regulators see it, and its per-sample pieces (ROS-free).

The model, with the override ratio ``r`` (1.0 = programmed feed)::

    v_c   = r · f_prog · N                      commanded feed [mm/min]
    v'_a  = v_c / (1 + τ_s s)                   the CNC interpolator's response, τ_s = 0.17 s   (Eq. 1)
    v_a   = v'_a / N                            feed per revolution [mm/rev]                      (Eq. 2)
    F_c   = K_s d v_a / (1 + τ_c s)             cutting force [N], τ_c = 60 (1 − e⁻¹) / N        (Eqs. 3, 4)

Combined (Eq. 5), with x = F_c [N] and u = v_c [mm/min]:
``ẍ = a1 x + a2 ẋ + b u``, ``a1 = −1/(τ_s τ_c)``, ``a2 = −(τ_s + τ_c)/(τ_s τ_c)``,
``b = K_s d / (N τ_s τ_c)``. The depth d enters before the τ_c lag (so b
carries d(t), as Eq. 5 states). :class:`FirstOrderLag` is the exact
discretisation of ``1/(1 + τ s)`` under a held input, used for both lags by
the plant and by the regulators' own models; :class:`DepthSchedule` is the
validated ``[[t_s, depth_mm], ...]`` of the plant and of the preview.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from cnc_contour_control.core.config import require_finite, require_non_negative
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param

#: τ_c = CHIP_TIME_FACTOR / N [s with N in rpm]: Eq. 4's 60 (1 − e⁻¹).
CHIP_TIME_FACTOR = 60.0 * (1.0 - math.exp(-1.0))


def lag_pole(dt_s: float, tau_s: float) -> float:
    """The discrete pole ``exp(−dt/τ)`` of ``1/(1 + τ s)`` under a zero-order hold (τ = 0: 0, no lag)."""
    return math.exp(-dt_s / tau_s) if tau_s > 0.0 else 0.0


class FirstOrderLag:
    """``y' = (u − y)/τ`` stepped exactly for a held input: ``y ← p y + (1 − p) u``, ``p = exp(−dt/τ)``.

    Parameters
    ----------
    tau_s : float
        Time constant [s], >= 0 (0: the output follows the input at once).
    value : float
        Initial output (any unit; the input's).
    """

    def __init__(self, tau_s: float, value: float = 0.0) -> None:
        self.tau_s = require_non_negative("tau_s", tau_s)
        self.value = float(value)
        self._dt_s = -1.0
        self._pole = 0.0

    def reset(self, value: float = 0.0) -> None:
        """Set the output (steady at ``value``)."""
        self.value = float(value)

    def step(self, dt_s: float, held_input: float) -> float:
        """Advance ``dt_s`` [s] with ``held_input`` held; return the new output."""
        if dt_s != self._dt_s:
            self._dt_s, self._pole = dt_s, lag_pole(dt_s, self.tau_s)
        self.value = self._pole * self.value + (1.0 - self._pole) * held_input
        return self.value


class DepthSchedule:
    """Depth of cut against time: ``[[t_s, depth_mm], ...]``, held from each time on.

    Parameters
    ----------
    points : sequence of (t_s, depth_mm)
        Non-empty; times finite and strictly increasing, depths finite and >= 0.
        Before the first time the first depth holds.
    """

    def __init__(self, points: Sequence[Sequence[float]]) -> None:
        if isinstance(points, (str, bytes)) or len(points) == 0:
            raise ConfigError(f"depth_schedule must be a non-empty list of [t_s, depth_mm], got {points!r}")
        rows = [self._row(i, p) for i, p in enumerate(points)]
        for i in range(1, len(rows)):
            if rows[i][0] <= rows[i - 1][0]:
                raise ConfigError(f"depth_schedule[{i}].t_s must be > {rows[i - 1][0]} (sorted), got {rows[i][0]}")
        self.points: tuple[tuple[float, float], ...] = tuple(rows)

    @staticmethod
    def _row(index: int, point: Sequence[float]) -> tuple[float, float]:
        if isinstance(point, (str, bytes)) or len(point) != 2:
            raise ConfigError(f"depth_schedule[{index}] must be [t_s, depth_mm], got {point!r}")
        t_s = require_finite(f"depth_schedule[{index}].t_s", point[0])
        return t_s, require_non_negative(f"depth_schedule[{index}].depth_mm", point[1])

    def depth_mm(self, t_s: float) -> float:
        """The depth [mm] at time ``t_s`` [s]."""
        depth = self.points[0][1]
        for time_s, value in self.points:
            if time_s > t_s:
                break
            depth = value
        return depth

    def step_times_s(self) -> tuple[float, ...]:
        """The times [s] at which the depth changes."""
        return tuple(t for (t, d), (_, before) in zip(self.points[1:], self.points) if d != before)

    def as_lists(self) -> list[list[float]]:
        """Plain ``[[t_s, depth_mm], ...]``."""
        return [list(p) for p in self.points]


@dataclass(frozen=True)
class TurningModelConfig:
    """The nominal model of Eqs. 1-5 that a regulator is designed on (defaults: the paper's scenario).

    Parameters
    ----------
    specific_force_n_mm2 : float
        K_s [N/mm²] (SM45C: 1773), in [1, 1e5].
    spindle_rpm : float
        N [rev/min], in [1, 1e5].
    programmed_feed_mm_rev : float
        The programmed feed f_prog [mm/rev] that an override ratio of 1 gives, in [1e-6, 100].
    interpolator_tau_s : float
        τ_s, the CNC interpolator's response to the override [s], in [0, 10].
    depth_min_mm, depth_max_mm : float
        Bounds of the depth of cut [mm] the regulator must cope with, 0 < min <= max.
    """

    specific_force_n_mm2: float = param(1773.0, unit="N/mm^2", low=1.0, high=1.0e5,
                                        description="specific cutting force K_s")
    spindle_rpm: float = param(600.0, unit="rev/min", low=1.0, high=1.0e5, description="spindle speed N")
    programmed_feed_mm_rev: float = param(0.2, unit="mm/rev", low=1.0e-6, high=100.0,
                                          description="programmed feed (override ratio 1)")
    interpolator_tau_s: float = param(0.17, unit="s", low=0.0, high=10.0,
                                      description="interpolator time constant tau_s (Eq. 1)")
    depth_min_mm: float = param(1.0, unit="mm", low=1.0e-6, high=1.0e3, description="smallest depth of cut")
    depth_max_mm: float = param(3.0, unit="mm", low=1.0e-6, high=1.0e3, description="largest depth of cut")

    def __post_init__(self) -> None:
        check_ranges(self, "model")
        if self.depth_max_mm < self.depth_min_mm:
            raise ConfigError(f"model.depth_max_mm must be >= depth_min_mm ({self.depth_min_mm}), "
                              f"got {self.depth_max_mm}")

    @property
    def chip_tau_s(self) -> float:
        """τ_c = 60 (1 − e⁻¹)/N [s] (Eq. 4)."""
        return CHIP_TIME_FACTOR / self.spindle_rpm

    @property
    def programmed_feed_mm_min(self) -> float:
        """The feed [mm/min] at override ratio 1."""
        return self.programmed_feed_mm_rev * self.spindle_rpm

    def steady_force_n(self, ratio: float, depth_mm: float) -> float:
        """The steady force [N] at override ``ratio`` and depth ``depth_mm``: K_s d f_prog r."""
        return self.specific_force_n_mm2 * depth_mm * self.programmed_feed_mm_rev * ratio

    def steady_ratio(self, force_n: float, depth_mm: float) -> float:
        """The override ratio that holds ``force_n`` [N] at ``depth_mm`` (inf at depth 0)."""
        gain = self.steady_force_n(1.0, depth_mm)
        return force_n / gain if gain > 0.0 else math.inf

    def eq5(self, depth_mm: float) -> tuple[float, float, float]:
        """Eq. 5's ``(a1 [1/s²], a2 [1/s], b [N/(s²·mm/min)])`` at ``depth_mm`` (needs τ_s > 0)."""
        tau_s, tau_c = self.interpolator_tau_s, self.chip_tau_s
        if tau_s <= 0.0:
            raise ConfigError(f"model.interpolator_tau_s must be > 0 for Eq. 5, got {tau_s}")
        product = tau_s * tau_c
        gain = self.specific_force_n_mm2 * depth_mm / (self.spindle_rpm * product)
        return -1.0 / product, -(tau_s + tau_c) / product, gain
