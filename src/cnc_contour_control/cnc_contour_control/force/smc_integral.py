"""Paper 004's SMC for a quantised override: the paper's law to reach the layer, an integral to stay in it.

With a 4-bit switch and a sampled loop the paper's boundary layer does not
hold: inside it the law is a proportional-derivative loop whose gain k/Φ must
beat the model's worst gain error β (Eq. 10), far too stiff for a 10 ms
update behind the τ_s and τ_c lags, so the override bangs between its end
levels. This law keeps the two phases apart, with hysteresis between them::

    reaching (|s| − λ q > m Φ, a depth jump, or not yet inside Φ):  the paper's SMC (:mod:`.smc`), s = ẋ + λ x̃
    sliding  (entered when |s| <= Φ):            r ← clip(r + dt k_I (F_ref − F)/Ĝ, 0, r_max)
                                                 (no change while |F_ref − F| <= δ F_ref, or while the
                                                 switch holds a level off r whose steady force
                                                 F r_applied/r_c is within h F_ref: that level lands)
    Ĝ = K_s f_prog d̂ [N per unit ratio],  d̂ = F/(K_s f_prog r_a) clipped to [d_min, d_max]
    r_a: the applied ratios through the model's τ_s lag (the feed the axis has now); r_c: r_a through τ_c
    q = min(|x̃|, Ĝ Δ) while the switch holds a level off r within one level Ĝ Δ of F_ref, else 0

Entering the sliding phase, r starts at r_a (bumpless). The integral makes
the loop an integrator of rate k_I [1/s] whatever the depth (Ĝ normalises the
gain); over any steady cycle between two levels its state returns, so the
force's mean sits at the reference (within δ) where no level lands. Where one
lands, but outside δ, the integral alone would walk off it to the next level and
back (a slow cycle of ±5-10 %); the hold band keeps it (with a continuous
override the switch holds no level off r, so the integral runs on). Where the
levels lie far apart (Ĝ Δ > m Φ/λ = 100 N at the defaults), the level next to
the reference can sit so far from it that λ x̃ alone passes m Φ and the paper's
law would bang the switch: the exit test discounts that part (q). A depth
step drives ẋ, and with it s, far outside m Φ within an update or two, so the
paper's law cuts the feed. The first update after a step may hold only a
millisecond of its rise (a 0.8 % force change at 2 -> 3 mm), too little for
s; the depth jump catches it: inverting one update of the τ_c lag,

    d_k = (F_k − p F_{k−1}) / ((1 − p) K_s f_prog r̄_a),   p = exp(−dt/τ_c),   r̄_a the mean axis feed

is the depth that explains this update's force (a 1 ms rise moves it by
5 %). The sliding phase ends when |d_k − d_{k−1}| > max(j, 5 RMS) |d_{k−1}|,
j the jump fraction and RMS that of the relative change over settled updates
(measurement noise raises the threshold instead of tripping it), tested only
while r_a has settled within 1 % of its level for 20 updates (a level change
moves r_a in a way the axis may not follow exactly).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from cnc_contour_control.core.force_model import FirstOrderLag, lag_pole
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.force.smc import SmcConfig, SmcLaw

#: The depth-jump test runs only while the modelled axis feed is within this fraction of the applied level,
#: after this many such updates in a row (the first ones learn the estimate's jitter).
SETTLED_FRACTION = 0.01
SETTLED_UPDATES = 20
#: The test's threshold is at least this many RMS of the estimate's change per update while settled (the mean
#: square over the settled updates, then each update weighted this), so noise raises it instead of tripping it.
JITTER_FACTOR = 5.0
JITTER_WEIGHT = 0.02
#: Below this mean axis feed [ratio] the force does not tell the depth.
MIN_RATIO = 0.05


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
    level_step_ratio : float
        The switch's level spacing Δ [ratio] (the quantiser's ``step_ratio``), in [0, 10]: the exit test
        discounts up to one level's force while the switch holds a level next to the reference (0: none).
    hold_band_fraction : float
        No integration while the held level's steady force F r_applied/r_a is within h F_ref, h in [0, 0.5]
        (0: off; module docstring).
    depth_jump_fraction : float
        The sliding phase ends when the depth estimate of one update moves by more than j (relative), j in
        [0, 10] (0: no depth-jump test; module docstring).
    """

    integral_per_s: float = param(2.0, unit="1/s", low=0.0, high=100.0, description="sliding-phase integral rate")
    exit_factor: float = param(4.0, low=1.0, high=1.0e3, description="sliding phase ends when |s| > factor * Phi")
    deadband_fraction: float = param(0.01, low=0.0, high=0.5, description="no integration within this error")
    ratio_max: float = param(1.5, low=0.0, high=10.0, description="clamp of the integral state")
    level_step_ratio: float = param(0.1, low=0.0, high=10.0,
                                    description="the switch's level spacing the exit test allows for (0: none)")
    hold_band_fraction: float = param(0.05, low=0.0, high=0.5,
                                      description="no integration while the held level's steady force is within "
                                                  "this fraction of the reference (0: off)")
    depth_jump_fraction: float = param(0.02, low=0.0, high=10.0,
                                       description="sliding phase ends when the one-update depth estimate "
                                                   "moves by more than this fraction (0: off)")

    def __post_init__(self) -> None:
        super().__post_init__()
        check_ranges(self, "smc_integral")


class SmcIntegralLaw:
    """Reaching by the paper's SMC, sliding by a gain-normalised integral (module docstring)."""

    def __init__(self, config: SmcIntegralConfig) -> None:
        self.config = config
        self.smc = SmcLaw(config)
        self._feed = FirstOrderLag(config.model.interpolator_tau_s, 1.0)
        self._chip = FirstOrderLag(config.model.chip_tau_s, 1.0)
        self.sliding, self.ratio, self._applied = False, 1.0, 1.0
        self._previous_n: float | None = None
        self._depth_mm: float | None = None
        self._settled, self._jitter_sq = 0, 0.0

    def reset(self, ratio: float = 1.0) -> None:
        """Steady at ``ratio``: in the sliding phase, the integral and the axis feed at ``ratio``."""
        self.smc.reset(ratio)
        self._feed.reset(ratio)
        self._chip.reset(ratio)
        self.sliding, self.ratio, self._applied = True, float(ratio), float(ratio)
        self._previous_n, self._depth_mm = None, None
        self._settled, self._jitter_sq = 0, 0.0

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

    def _depth_jumped(self, dt_s: float, force_n: float, before: float, actual: float) -> bool:
        """Whether the depth that explains this update's force moved by more than the jump threshold.

        One update of the τ_c lag inverted: F = p F_prev + (1 − p) K_s f_prog d r̄_a, r̄_a the mean axis feed
        over the update, p = exp(−dt/τ_c); tested only while the modelled feed has settled on its level.
        """
        model, previous, last_depth = self.config.model, self._previous_n, self._depth_mm
        self._previous_n, self._depth_mm = force_n, None
        mean_ratio = 0.5 * (before + actual)
        if previous is None or mean_ratio < MIN_RATIO:
            return False
        pole = lag_pole(dt_s, model.chip_tau_s)
        self._depth_mm = (force_n - pole * previous) / ((1.0 - pole) * model.steady_force_n(mean_ratio, 1.0))
        if last_depth is None or abs(actual - self._applied) > SETTLED_FRACTION * actual:
            self._settled = 0
            return False
        change = abs(self._depth_mm - last_depth) / max(abs(last_depth), 1.0e-9)
        threshold = max(self.config.depth_jump_fraction, JITTER_FACTOR * math.sqrt(self._jitter_sq))
        if self.config.depth_jump_fraction > 0.0 and self._settled >= SETTLED_UPDATES and change > threshold:
            return True
        self._settled += 1
        self._jitter_sq += max(JITTER_WEIGHT, 1.0 / self._settled) * (change * change - self._jitter_sq)
        return False

    def _holds_level(self, chip_ratio: float) -> bool:
        """Whether the switch holds a level off the integral's state (never with a continuous override) and the
        feed the force has, r_c (the axis feed through the τ_c lag), is large enough to scale its force."""
        return chip_ratio >= MIN_RATIO and abs(self._applied - self.ratio) > 1.0e-9

    def _quantisation_n(self, force_n: float, reference_n: float, level_n: float, actual: float) -> float:
        """The part of |F − F_ref| [N] the switch explains: up to one level's force Ĝ Δ while the held level's
        steady force is within one level of the reference (a level next to it), else none."""
        step_n = self.config.level_step_ratio * self._gain_n(force_n, actual)
        if abs(level_n - reference_n) > step_n:
            return 0.0
        return min(abs(force_n - reference_n), step_n)

    def step(self, dt_s: float, force_n: float, reference_n: float) -> float:
        """One update (module docstring); returns the requested ratio."""
        cfg = self.config
        before = self._feed.value
        actual = self._feed.step(dt_s, self._applied)
        jumped = self._depth_jumped(dt_s, force_n, before, actual)
        chip_ratio = self._chip.step(dt_s, 0.5 * (before + actual))
        reaching = self.smc.step(dt_s, force_n, reference_n)
        held = self._holds_level(chip_ratio)
        level_n = force_n * self._applied / chip_ratio if held else math.inf  # the held level's steady force
        phi, surface = cfg.boundary_layer_n_s(reference_n), abs(self.smc.surface_n_s)
        exit_surface = surface - cfg.lambda_per_s * self._quantisation_n(
            force_n, reference_n, level_n, actual)
        if self.sliding and (exit_surface > cfg.exit_factor * phi or jumped):
            self.sliding = False
        elif not self.sliding and surface <= phi:
            self.sliding, self.ratio = True, actual
        if not self.sliding:
            return reaching
        error_n = reference_n - force_n
        outside = abs(error_n) > cfg.deadband_fraction * reference_n
        lands = abs(level_n - reference_n) <= cfg.hold_band_fraction * reference_n
        if outside and not lands:
            self.ratio += dt_s * cfg.integral_per_s * error_n / self._gain_n(force_n, actual)
        self.ratio = min(max(self.ratio, 0.0), cfg.ratio_max)
        return self.ratio
