"""The SMC with an integral in its boundary layer, and the switch's hysteresis (tier 1, core maths)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.force import ForceRegulatorConfig, TurningModelConfig, make_force_law
from cnc_contour_control.force.smc_integral import SmcIntegralConfig, SmcIntegralLaw

MODEL = TurningModelConfig(depth_min_mm=1.0, depth_max_mm=3.0)
PARAMS = {"eta_n_s2": 1.0e5, "integral_per_s": 2.0, "model": MODEL}
DT_S = 0.01


def steady_law(ratio: float) -> SmcIntegralLaw:
    law = SmcIntegralLaw(SmcIntegralConfig(**PARAMS))
    law.reset(ratio)
    law.note_applied(ratio)
    return law


def test_within_the_dead_band_the_ratio_holds() -> None:
    law = steady_law(0.7)
    assert law.step(DT_S, 496.4, 500.0) == 0.7 and law.sliding


@pytest.mark.parametrize("depth_mm", [1.0, 2.0, 3.0])
def test_the_integral_moves_the_ratio_by_the_relative_error_at_any_depth(depth_mm: float) -> None:
    ratio = MODEL.steady_ratio(450.0, depth_mm)
    law = steady_law(ratio)
    law.step(DT_S, 450.0, 500.0)  # a held force: the surface is λ x̃ = −1000 N/s, inside 4 Φ
    assert law.sliding
    assert law.ratio / ratio - 1.0 == pytest.approx(DT_S * 2.0 * 50.0 / 450.0, rel=1e-9)


def test_a_depth_step_leaves_the_layer_and_cuts_the_feed() -> None:
    law = steady_law(0.7)
    law.step(DT_S, 500.0, 500.0)
    requested = law.step(DT_S, 536.0, 500.0)  # 36 N in 10 ms: ẋ = 3600 N/s, s > 4 Φ = 2000 N/s
    assert not law.sliding and requested < 0.0


STEADY_N = MODEL.steady_force_n(0.7, 2.0)  # 496.4 N: 70 % at 2 mm
#: 2 -> 3 mm seen 1 ms after the step: the new depth's half more through the τ_c lag, 3.9 N
FIRST_MS_N = STEADY_N * (1.0 + 0.5 * (1.0 - math.exp(-1.0e-3 / MODEL.chip_tau_s)))


def settled_law(jump_fraction: float) -> SmcIntegralLaw:
    law = SmcIntegralLaw(SmcIntegralConfig(eta_n_s2=1.0e5, integral_per_s=2.0, model=MODEL,
                                           depth_jump_fraction=jump_fraction))
    law.reset(0.7)
    law.note_applied(0.7)
    return law


@pytest.mark.parametrize(("jump_fraction", "cuts"), [(0.02, True), (0.0, False)])
def test_a_depth_steps_first_millisecond_ends_the_sliding_phase(jump_fraction: float, cuts: bool) -> None:
    law = settled_law(jump_fraction)
    for _ in range(25):
        assert law.step(DT_S, STEADY_N, 500.0) == 0.7
    requested = law.step(DT_S, FIRST_MS_N, 500.0)  # ẋ = 390 N/s: |s| < Φ, the surface alone sees nothing
    assert law.sliding is not cuts
    assert (requested < 0.0) is cuts, f"requested {requested}"


def test_measurement_noise_raises_the_depth_jump_threshold_instead_of_tripping_it() -> None:
    law = settled_law(0.02)
    noise_n = np.random.default_rng(7).normal(0.0, 1.0, 1000)  # 1 N: a 1.8 % RMS change of the estimate
    for k, noise in enumerate(noise_n):
        law.step(DT_S, STEADY_N + noise, 500.0)
        assert law.sliding, f"left the layer on noise at update {k}"


def test_while_the_axis_feed_moves_the_depth_jump_is_not_tested() -> None:
    law = settled_law(0.02)
    for _ in range(25):
        law.step(DT_S, STEADY_N, 500.0)
    law.note_applied(0.8)  # a level up: the modelled feed moves for about 3 τ_s
    law.step(DT_S, STEADY_N, 500.0)
    law.step(DT_S, FIRST_MS_N, 500.0)
    assert law.sliding


@pytest.mark.parametrize(("applied", "hold_band", "holds"), [(0.7, 0.05, True), (0.72, 0.05, False),
                                                            (0.7, 0.0, False)])
def test_a_held_level_that_lands_stops_the_integral(applied: float, hold_band: float, holds: bool) -> None:
    """480 N (−4 %) at 2 mm: 0.7 lands; 0.72 (a continuous override at the integral's state) is no held level."""
    law = SmcIntegralLaw(SmcIntegralConfig(eta_n_s2=1.0e5, integral_per_s=2.0, model=MODEL,
                                           hold_band_fraction=hold_band))
    law.reset(applied)
    law.ratio = 0.72  # the integral's state, off the level the switch holds (0.72 is within 0.75 of 0.7)
    law.note_applied(applied)
    force_n = 480.0 * applied / 0.7
    law.step(DT_S, force_n, 500.0)
    assert law.sliding
    assert (law.ratio == 0.72) is holds, f"ratio {law.ratio}"


@pytest.mark.parametrize(("level_step", "stays"), [(0.1, True), (0.0, False)])
def test_a_held_level_next_to_the_reference_does_not_end_the_sliding_phase(level_step: float, stays: bool) -> None:
    """30 % at 2.97 mm, 0.25 mm/rev, 400 rpm: 394.9 N, λ x̃ = −2100 N/s beyond 4 Φ; 40 % gives 526.6 N."""
    model = TurningModelConfig(spindle_rpm=400.0, programmed_feed_mm_rev=0.25, depth_min_mm=1.0, depth_max_mm=3.0)
    law = SmcIntegralLaw(SmcIntegralConfig(eta_n_s2=1.0e5, integral_per_s=2.0, model=model,
                                           level_step_ratio=level_step))
    law.reset(0.3)
    law.ratio = 0.33  # the integral on its way up, the switch still at 30 %
    law.note_applied(0.3)
    force_n = model.steady_force_n(0.3, 2.97)
    for _ in range(3):
        law.step(DT_S, force_n, 500.0)
    assert law.sliding is stays


def test_back_in_the_layer_the_integral_starts_from_the_axis_feed() -> None:
    law = steady_law(0.7)
    law.step(DT_S, 500.0, 500.0)
    law.step(DT_S, 536.0, 500.0)
    law.note_applied(0.0)
    law.step(DT_S, 536.0, 500.0)  # ẋ = 0, λ x̃ = 720 N/s: inside 4 Φ but outside Φ, still reaching
    assert not law.sliding
    law.step(DT_S, 510.0, 500.0)  # ẋ = −2600: |s| = 2400 > Φ
    law.step(DT_S, 505.0, 500.0)  # ẋ = −500, λ x̃ = 100: |s| = 400 <= Φ = 500
    feed = 0.7 * math.exp(-3 * DT_S / MODEL.interpolator_tau_s)  # three updates at 0 % since the cut
    assert law.sliding and law.ratio == pytest.approx(feed, rel=1e-12), "5 N is within the 1 % dead band"


@pytest.mark.parametrize(("params", "name"), [({"integral_per_s": -1.0}, "integral_per_s"),
                                               ({"exit_factor": 0.5}, "exit_factor"),
                                               ({"deadband_fraction": 0.9}, "deadband_fraction"),
                                               ({"depth_jump_fraction": -0.1}, "depth_jump_fraction"),
                                               ({"hold_band_fraction": 0.6}, "hold_band_fraction")])
def test_a_bad_option_is_refused_naming_it(params: dict[str, float], name: str) -> None:
    with pytest.raises(ConfigError, match=name):
        make_force_law("smc_integral", params)


def test_a_bad_hysteresis_is_refused_naming_it() -> None:
    with pytest.raises(ConfigError, match="hysteresis_fraction"):
        ForceRegulatorConfig(hysteresis_fraction=-0.1)
