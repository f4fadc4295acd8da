"""Paper 004's SMC for a quantised override: the paper's law to reach the layer, an integral to stay in it.

With a 4-bit switch and a sampled loop the paper's boundary layer does not
hold: inside it the law is a proportional-derivative loop whose gain k/Φ must
beat the model's worst gain error β (Eq. 10), far too stiff for a 10 ms
update behind the τ_s and τ_c lags, so the override bangs between its end
levels. This law keeps the two phases apart, with hysteresis between them::

    reaching (|s| > m Φ, or not yet inside Φ):   the paper's SMC (:mod:`.smc`), s = ẋ + λ x̃
    sliding  (entered when |s| <= Φ):            r ← clip(r + dt k_I (F_ref − F)/Ĝ, 0, r_max)
                                                 (no change while |F_ref − F| <= δ F_ref)
    Ĝ = K_s f_prog d̂ [N per unit ratio],  d̂ = F/(K_s f_prog r_a) clipped to [d_min, d_max]
    r_a: the applied ratios through the model's τ_s lag (the feed the axis has now)

Entering the sliding phase, r starts at r_a (bumpless). The integral makes
the loop an integrator of rate k_I [1/s] whatever the depth (Ĝ normalises the
gain); over any steady cycle between two levels its state returns, so the
force's mean sits at the reference (within δ) where no level lands. A depth
step drives ẋ, and with it s, far outside m Φ at once, so the paper's law
cuts the feed at the first update after the step.
"""
from __future__ import annotations

from dataclasses import dataclass

from cnc_contour_control.core.force_model import FirstOrderLag
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.force.smc import SmcConfig, SmcLaw


@dataclass(frozen=True)
class SmcIntegralConfig(SmcConfig):
    """The paper's SMC (λ, η, ε, model) plus the sliding phase's integral.

    Parameters
    ----------
    integral_per_s : float
        Integral rate k_I of the sliding phase [1/s], in [0, 100].
    exit_factor : float
        The sliding phase ends when |s| > m Φ, m in [1, 1e3].
    deadband_fraction : float
        No integration while |F_ref − F| <= δ F_ref, δ in [0, 0.5].
    ratio_max : float
        Clamp of the integral state [ratio], in [0, 10] (the switch's top).
    """

    integral_per_s: float = param(2.0, unit="1/s", low=0.0, high=100.0, description="sliding-phase integral rate")
    exit_factor: float = param(4.0, low=1.0, high=1.0e3, description="sliding phase ends when |s| > factor * Phi")
    deadband_fraction: float = param(0.01, low=0.0, high=0.5, description="no integration within this error")
    ratio_max: float = param(1.5, low=0.0, high=10.0, description="clamp of the integral state")

    def __post_init__(self) -> None:
        super().__post_init__()
        check_ranges(self, "smc_integral")


class SmcIntegralLaw:
    """Reaching by the paper's SMC, sliding by a gain-normalised integral (module docstring)."""

    def __init__(self, config: SmcIntegralConfig) -> None:
        self.config = config
        self.smc = SmcLaw(config)
        self._feed = FirstOrderLag(config.model.interpolator_tau_s, 1.0)
        self.sliding, self.ratio, self._applied = False, 1.0, 1.0

    def reset(self, ratio: float = 1.0) -> None:
        """Steady at ``ratio``: in the sliding phase, the integral and the axis feed at ``ratio``."""
        self.smc.reset(ratio)
        self._feed.reset(ratio)
        self.sliding, self.ratio, self._applied = True, float(ratio), float(ratio)

    def set_depth_mm(self, depth_mm: float) -> None:
        """The reaching law's model depth (the integral estimates its own gain)."""
        self.smc.set_depth_mm(depth_mm)

    def note_applied(self, ratio: float) -> None:
        """The applied ratio drives the model of the axis feed."""
        self._applied = float(ratio)

    def _gain_n(self, force_n: float, actual_ratio: float) -> float:
        """Ĝ [N per unit ratio] from the force and the axis feed, its depth within the model's bounds."""
        model = self.config.model
        per_mm = model.steady_force_n(1.0, 1.0)
        depth = force_n / (per_mm * actual_ratio) if actual_ratio > 0.0 else model.depth_max_mm
        return per_mm * min(max(depth, model.depth_min_mm), model.depth_max_mm)

    def step(self, dt_s: float, force_n: float, reference_n: float) -> float:
        """One update (module docstring); returns the requested ratio."""
        cfg = self.config
        actual = self._feed.step(dt_s, self._applied)
        reaching = self.smc.step(dt_s, force_n, reference_n)
        phi, surface = cfg.boundary_layer_n_s(reference_n), abs(self.smc.surface_n_s)
        if self.sliding and surface > cfg.exit_factor * phi:
            self.sliding = False
        elif not self.sliding and surface <= phi:
            self.sliding, self.ratio = True, actual
        if not self.sliding:
            return reaching
        error_n = reference_n - force_n
        if abs(error_n) > cfg.deadband_fraction * reference_n:
            self.ratio += dt_s * cfg.integral_per_s * error_n / self._gain_n(force_n, actual)
        self.ratio = min(max(self.ratio, 0.0), cfg.ratio_max)
        return self.ratio
