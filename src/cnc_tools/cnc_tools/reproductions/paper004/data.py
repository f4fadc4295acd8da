"""Paper 004's stated numbers and claims, and issue 12's estimates of the physical floors (data, printed beside ours).

Source: ``../shared/seeds/004_a865f1e934d0c0c7.txt`` (sections 2-4), digest in
``../shared/spec/seeds.md``. The paper gives no tables: its results are
Figs. 1, 2, 4, 5 and the claims below; the floors are issue 12's estimates
from the paper's model, which the bench recomputes.
"""
from __future__ import annotations

#: The scenario of Figs. 1-5.
REFERENCE_N = 500.0
PROGRAMMED_FEED_MM_REV = 0.2
SPINDLE_RPM = 600.0
DURATION_S = 12.0
DEPTH_SCHEDULE: tuple[tuple[float, float], ...] = ((0.0, 1.0), (4.0, 2.0), (8.0, 3.0))
#: Eq. 1 and section 4.
INTERPOLATOR_TAU_S = 0.17
SPECIFIC_FORCE_N_MM2 = 1773.0
SMC_PARAMS = {"lambda_per_s": 20.0, "eta_n_s2": 0.1, "epsilon_fraction": 0.05}
#: Ours for the 4-bit switch (law ``smc_integral``, not the paper's): its λ and ε, η raised to reach from any
#: start, an integral in the layer; with the regulator's hysteresis (a fraction of a level).
OURS_PARAMS = {"lambda_per_s": 20.0, "eta_n_s2": 1.0e5, "epsilon_fraction": 0.05, "integral_per_s": 2.0}
OURS_HYSTERESIS = 0.25
#: The FANUC 0T switch: 0-150 % in 10 % steps.
SWITCH = {"step_ratio": 0.1, "min_ratio": 0.0, "max_ratio": 1.5}
#: Settling band of the bench (± fraction of the reference), the paper's ε.
BAND_FRACTION = 0.05

#: Issue 12's estimates (from the model, not from the paper): overshoot floor [%] and fastest settling [s] per step.
ISSUE_FLOOR_OVERSHOOT_PCT = {(1.0, 2.0): 39.0, (2.0, 3.0): 15.0}
ISSUE_FLOOR_SETTLING_S = {(1.0, 2.0): 0.16, (2.0, 3.0): 0.10}
#: 500 N at 1 mm needs about 141 % override; at 3 mm 40 % gives about 426 N and 50 % about 532 N.
ISSUE_RATIO_AT_1MM_PCT = 141.0
ISSUE_FORCE_AT_3MM_N = {0.4: 426.0, 0.5: 532.0}

#: The paper's qualitative claims (Figs. 1, 2, 4, 5), checked by the bench.
CLAIMS = {
    "adaptive_overshoots": "adaptive, no quantisation: tracks, but overshoots at each depth step (Fig. 1)",
    "adaptive_oscillates": "adaptive, 4-bit: overshoots and oscillates around the reference (Fig. 2)",
    "smc_less_overshoot": "SMC: much less overshoot than adaptive (Figs. 4, 5 vs 1, 2)",
    "smc_bounded_chatter": "SMC, 4-bit: more chattering, but bounded (Fig. 5)",
    "phi_sets_chatter": "a wider boundary layer (larger epsilon, Phi) suppresses the chattering (section 4)",
}
