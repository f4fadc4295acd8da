"""The adaptive baseline: an integral force loop normalised by an on-line estimate of the process gain.

Paper 004 compares with "adaptive control" of its refs. 1-8 without stating
the law. Their common form (Masory and Koren's constant-force turning
controller; Tomizuka and Zhang's adaptive I/PI) is kept here: estimate the
process gain K = K_s d [N per mm/rev] on line and scale an integral law by
1/K̂, so the loop keeps its designed speed whatever the depth::

    φ  = lag_c(lag_s(r_applied f_prog))      modelled feed per rev [mm/rev] (Eqs. 1-4, nominal τ_s, τ_c)
    K̂ ← RLS(F ≈ K̂ φ, forgetting ρ)           recursive least squares, one parameter
    r  ← clip(r + dt/τ_cl · (F_ref − F)/(K̂ f_prog), 0, ratio_max)

It overshoots at a depth step by construction: the force rises before the
estimate or the integral can react. A preview's depth sets K̂ = K_s d.
"""
from __future__ import annotations

from dataclasses import dataclass

from cnc_contour_control.core.config import require_positive
from cnc_contour_control.core.force_model import FirstOrderLag, TurningModelConfig
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.force.base import check_sample
from cnc_contour_control.force.smc import nested_model


@dataclass(frozen=True)
class AdaptiveConfig:
    """The adaptive integral law.

    Parameters
    ----------
    loop_tau_s : float
        Designed time constant τ_cl of the normalised integral loop [s], in [1e-3, 100].
    forgetting : float
        RLS forgetting factor ρ per update, in [0.5, 1].
    ratio_max : float
        Clamp of the law's ratio, in [0, 10].
    model : TurningModelConfig
        The nominal model (lags and the initial K̂ at sqrt(d_min d_max)); a mapping is validated.
    """

    loop_tau_s: float = param(0.5, unit="s", low=1.0e-3, high=100.0, description="integral loop time constant")
    forgetting: float = param(0.98, low=0.5, high=1.0, description="RLS forgetting factor per update")
    ratio_max: float = param(1.5, low=0.0, high=10.0, description="clamp of the law's ratio (anti-windup)")
    model: TurningModelConfig = param(default_factory=TurningModelConfig, description="nominal turning model")

    def __post_init__(self) -> None:
        check_ranges(self, "adaptive")
        object.__setattr__(self, "model", nested_model(self.model))


class AdaptiveLaw:
    """The adaptive integral law (module docstring)."""

    def __init__(self, config: AdaptiveConfig) -> None:
        self.config = config
        model = config.model
        self._lag_s = FirstOrderLag(model.interpolator_tau_s)
        self._lag_c = FirstOrderLag(model.chip_tau_s)
        self.reset(1.0)

    def reset(self, ratio: float = 1.0) -> None:
        """Steady cutting at ``ratio``; K̂ at the nominal depth, its covariance large."""
        model = self.config.model
        self.ratio = self._applied = float(ratio)
        feed = ratio * model.programmed_feed_mm_rev
        self._lag_s.reset(feed)
        self._lag_c.reset(feed)
        self.gain_n_per_mm = model.specific_force_n_mm2 * (model.depth_min_mm * model.depth_max_mm) ** 0.5
        self._covariance = 1.0e6

    def set_depth_mm(self, depth_mm: float) -> None:
        """K̂ = K_s depth (the estimate goes on from there)."""
        self.gain_n_per_mm = self.config.model.specific_force_n_mm2 * require_positive("depth_mm", depth_mm)

    def note_applied(self, ratio: float) -> None:
        """The regressor's input from now on (the state itself is clamped to [0, ratio_max])."""
        self._applied = ratio

    def _estimate(self, dt_s: float, force_n: float) -> None:
        cfg = self.config
        phi = self._lag_c.step(dt_s, self._lag_s.step(dt_s, self._applied * cfg.model.programmed_feed_mm_rev))
        if phi <= 1.0e-9:
            return
        p = self._covariance
        gain = p * phi / (cfg.forgetting + phi * phi * p)
        self.gain_n_per_mm = max(self.gain_n_per_mm + gain * (force_n - self.gain_n_per_mm * phi), 1.0e-6)
        self._covariance = (p - gain * phi * p) / cfg.forgetting

    def step(self, dt_s: float, force_n: float, reference_n: float) -> float:
        """One update; returns the requested ratio."""
        check_sample(dt_s, force_n, reference_n)
        self._estimate(dt_s, force_n)
        cfg = self.config
        scale = dt_s / (cfg.loop_tau_s * self.gain_n_per_mm * cfg.model.programmed_feed_mm_rev)
        self.ratio = min(max(self.ratio + scale * (reference_n - force_n), 0.0), cfg.ratio_max)
        return self.ratio
