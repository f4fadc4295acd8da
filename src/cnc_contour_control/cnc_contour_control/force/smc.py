"""Paper 004's continuous sliding-mode force law (Slotine's boundary layer on the model of Eq. 5).

One update, with x = F_c [N], x_d = F_ref [N] (ẋ_d = ẍ_d = 0 between updates)::

    x̃ = x − x_d,   ẋ ≈ (x − x_prev)/dt,   s = ẋ + λ x̃                         (Eqs. 6, 7)
    f̂ = a1 x + a2 ẋ,   b̂ = b(d̂),   β = sqrt(d_max/d_min)
    k = η β + (β − 1) |f̂ + λ ẋ|                                                 (Eq. 10, worst b)
    u = [−f̂ − λ ẋ − k sat(s/Φ)] / b̂,   Φ = ε F_ref λ                           (Eqs. 9, 11)
    ratio = u / (f_prog N)

a1, a2, b̂ from :class:`~cnc_contour_control.core.force_model.TurningModelConfig`
(the nominal parameters); d̂ = sqrt(d_min d_max) (the geometric mean, for
which b̂/b spans [1/β, β]) until a preview sets it. Paper: λ = 20 /s,
η = 0.1 N/s², ε = 5 %.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.config import build_config, require_positive
from cnc_contour_control.core.force_model import TurningModelConfig
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.force.base import check_sample, sat


def nested_model(value: TurningModelConfig | Mapping[str, Any]) -> TurningModelConfig:
    """A model section given as a mapping, validated into :class:`TurningModelConfig`."""
    if isinstance(value, TurningModelConfig):
        return value
    return build_config(TurningModelConfig, value, context="model")


@dataclass(frozen=True)
class SmcConfig:
    """The sliding-mode law (defaults: the paper's λ, η, ε).

    Parameters
    ----------
    lambda_per_s : float
        Surface slope λ [1/s], in [1e-6, 1e4].
    eta_n_s2 : float
        Reaching margin η [N/s²] of ½ d(s²)/dt <= −η|s|, in [0, 1e9].
    epsilon_fraction : float
        Allowed tracking error ε as a fraction of the reference, in [1e-6, 1]; Φ = ε F_ref λ.
    model : TurningModelConfig
        The nominal model (a mapping is validated).
    """

    lambda_per_s: float = param(20.0, unit="1/s", low=1.0e-6, high=1.0e4, description="sliding surface slope lambda")
    eta_n_s2: float = param(0.1, unit="N/s^2", low=0.0, high=1.0e9, description="reaching margin eta")
    epsilon_fraction: float = param(0.05, low=1.0e-6, high=1.0,
                                    description="allowed error epsilon / reference (boundary layer Phi = eps*F*lambda)")
    model: TurningModelConfig = param(default_factory=TurningModelConfig, description="nominal turning model")

    def __post_init__(self) -> None:
        check_ranges(self, "smc")
        object.__setattr__(self, "model", nested_model(self.model))

    def boundary_layer_n_s(self, reference_n: float) -> float:
        """Φ = ε F_ref λ [N/s]; refuses a Φ that is not > 0."""
        return require_positive("boundary_layer_n_s", self.epsilon_fraction * reference_n * self.lambda_per_s)


class SmcLaw:
    """The continuous sliding-mode law of paper 004 (module docstring)."""

    def __init__(self, config: SmcConfig) -> None:
        self.config = config
        model = config.model
        self._beta = math.sqrt(model.depth_max_mm / model.depth_min_mm)
        self._depth_mm = math.sqrt(model.depth_max_mm * model.depth_min_mm)
        self._previous_n: float | None = None
        self.surface_n_s = 0.0

    def reset(self, ratio: float = 1.0) -> None:
        """Forget the previous force (the first update takes ẋ = 0)."""
        self._previous_n = None
        self.surface_n_s = 0.0

    def set_depth_mm(self, depth_mm: float) -> None:
        """Design on ``depth_mm`` [mm] (> 0) from now on: b̂ = b(depth_mm)."""
        self._depth_mm = require_positive("depth_mm", depth_mm)

    def note_applied(self, ratio: float) -> None:
        """Stateless in u: nothing to wind up."""

    def step(self, dt_s: float, force_n: float, reference_n: float) -> float:
        """One update (module docstring); returns the requested ratio."""
        check_sample(dt_s, force_n, reference_n)
        cfg, model = self.config, self.config.model
        rate = 0.0 if self._previous_n is None else (force_n - self._previous_n) / dt_s
        self._previous_n = force_n
        a1, a2, b_hat = model.eq5(self._depth_mm)
        lam = cfg.lambda_per_s
        self.surface_n_s = rate + lam * (force_n - reference_n)
        f_hat = a1 * force_n + a2 * rate
        gain = cfg.eta_n_s2 * self._beta + (self._beta - 1.0) * abs(f_hat + lam * rate)
        phi = cfg.boundary_layer_n_s(reference_n)
        u_mm_min = (-f_hat - lam * rate - gain * sat(self.surface_n_s / phi)) / b_hat
        return u_mm_min / model.programmed_feed_mm_min
