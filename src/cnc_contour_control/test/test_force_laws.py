"""Paper 004's force regulators (ROS-free): registry, bad input, the switch, the laws, the regulator, the preview."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.force import (
    FORCE_LAWS,
    DepthSchedule,
    FirstOrderLag,
    ForceRegulator,
    ForceRegulatorConfig,
    PreviewConfig,
    Quantiser,
    QuantiserConfig,
    TurningModelConfig,
    force_law_config,
    make_force_law,
    plan_step,
)
from cnc_contour_control.force.preview import sigma_delta

MODEL = TurningModelConfig()


class ModelLoop:
    """The paper's chain on the nominal model: ratio -> τ_s -> feed per rev -> K_s d -> τ_c (a test double)."""

    def __init__(self, depth_mm: float, force_n: float = 500.0) -> None:
        self.depth_mm = depth_mm
        feed = force_n / (MODEL.specific_force_n_mm2 * depth_mm)
        self.feed = FirstOrderLag(MODEL.interpolator_tau_s, feed)
        self.force = FirstOrderLag(MODEL.chip_tau_s, force_n)

    def step(self, dt_s: float, ratio: float) -> float:
        feed = self.feed.step(dt_s, ratio * MODEL.programmed_feed_mm_rev)
        return self.force.step(dt_s, MODEL.specific_force_n_mm2 * self.depth_mm * feed)


def close_loop(regulator: ForceRegulator, loop: ModelLoop, seconds: float, dt_s: float = 1e-3) -> np.ndarray:
    force, out = loop.force.value, []
    for _ in range(int(round(seconds / dt_s))):
        force = loop.step(dt_s, regulator.last.applied_ratio)
        regulator.step(dt_s, force, 500.0)
        out.append(force)
    return np.array(out)


# ---------------------------------------------------------------- registry and bad input
def test_registry_names_and_unknowns() -> None:
    assert sorted(FORCE_LAWS) == ["adaptive", "pi", "smc", "smc_integral"]
    names = r"\['adaptive', 'pi', 'smc', 'smc_integral'\]"
    with pytest.raises(ConfigError, match=rf"force_law must be one of {names}, got 'mpc'"):
        make_force_law("mpc")
    with pytest.raises(ConfigError, match="unknown key"):
        make_force_law("smc", {"lambda": 20.0})


@pytest.mark.parametrize("law", sorted(FORCE_LAWS))
@pytest.mark.parametrize("reference", [0.0, -500.0, math.nan, math.inf])
def test_bad_reference_is_refused_naming_the_value(law: str, reference: float) -> None:
    with pytest.raises(ConfigError, match=f"reference_n must be finite and > 0, got {reference!r}"):
        make_force_law(law).step(0.01, 400.0, reference)


@pytest.mark.parametrize("law", sorted(FORCE_LAWS))
def test_non_finite_force_faults(law: str) -> None:
    with pytest.raises(FaultError, match="force_n must be finite, got nan"):
        make_force_law(law).step(0.01, math.nan, 500.0)


@pytest.mark.parametrize("params, message", [
    ({"lambda_per_s": 0.0}, r"smc.lambda_per_s must be in \[1e-06, 10000.0\], got 0.0"),
    ({"lambda_per_s": -20.0}, "smc.lambda_per_s must be in"),
    ({"epsilon_fraction": 0.0}, "smc.epsilon_fraction must be in"),
    ({"eta_n_s2": -0.1}, "smc.eta_n_s2 must be in"),
    ({"model": {"depth_min_mm": 3.0, "depth_max_mm": 1.0}}, "model.depth_max_mm must be >= depth_min_mm"),
])
def test_bad_smc_parameters_are_refused(params: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        force_law_config("smc", params)


def test_boundary_layer_is_eps_ref_lambda_and_positive() -> None:
    config = force_law_config("smc")
    assert config.boundary_layer_n_s(500.0) == pytest.approx(0.05 * 500.0 * 20.0)


# ---------------------------------------------------------------- the switch
@pytest.mark.parametrize("requested, applied", [
    (1.41, 1.4), (1.46, 1.5), (0.44, 0.4), (0.45, 0.5), (2.3, 1.5), (-0.3, 0.0), (0.04, 0.0), (1.0, 1.0)])
def test_four_bit_switch_rounds_and_clips(requested: float, applied: float) -> None:
    assert Quantiser(QuantiserConfig())(requested) == pytest.approx(applied)


def test_switch_levels_and_continuous_mode() -> None:
    assert QuantiserConfig().levels == 16
    assert QuantiserConfig(step_ratio=0.05, max_ratio=2.0).levels == 41
    assert Quantiser(QuantiserConfig(step_ratio=0.0))(0.437) == 0.437


@pytest.mark.parametrize("low, high", [(0.0, 0.9), (1.1, 1.5)])
def test_switch_range_must_contain_one(low: float, high: float) -> None:
    with pytest.raises(ConfigError, match=rf"quantiser range \[{low}, {high}\] must contain 1.0"):
        QuantiserConfig(min_ratio=low, max_ratio=high)


# ---------------------------------------------------------------- the laws
def test_smc_is_the_papers_law() -> None:
    """Eqs. 5-11 written out independently for one update."""
    law = make_force_law("smc")
    law.step(0.01, 480.0, 500.0)
    ratio = law.step(0.01, 490.0, 500.0)
    tau_s, tau_c, n = 0.17, 60 * (1 - math.exp(-1)) / 600.0, 600.0
    d_hat, beta, lam = math.sqrt(3.0), math.sqrt(3.0), 20.0
    x, x_dot = 490.0, 1000.0
    f = -x / (tau_s * tau_c) - (tau_s + tau_c) / (tau_s * tau_c) * x_dot
    b_hat = 1773.0 * d_hat / (n * tau_s * tau_c)
    s = x_dot + lam * (x - 500.0)
    k = 0.1 * beta + (beta - 1) * abs(f + lam * x_dot)
    u = (-f - lam * x_dot - k * max(-1.0, min(1.0, s / (0.05 * 500 * lam)))) / b_hat
    assert ratio == pytest.approx(u / (0.2 * 600.0), rel=1e-12)


def test_smc_equivalent_control_holds_the_reference_on_the_design_depth() -> None:
    law = make_force_law("smc")
    law.set_depth_mm(2.0)
    assert law.step(0.01, 500.0, 500.0) == pytest.approx(MODEL.steady_ratio(500.0, 2.0))
    assert law.step(0.01, 500.0, 500.0) == pytest.approx(MODEL.steady_ratio(500.0, 2.0))


@pytest.mark.parametrize("depth_mm", [1.5, 2.0, 3.0])
def test_smc_keeps_the_error_within_the_boundary_layer(depth_mm: float) -> None:
    """Continuous switch: after the transient |x̃| <= ε F_ref (depths inside the design range)."""
    regulator = ForceRegulator(ForceRegulatorConfig(law="smc", quantiser={"step_ratio": 0.0}))
    regulator.reset(1.0)
    forces = close_loop(regulator, ModelLoop(depth_mm, force_n=400.0), 3.0)
    assert np.all(np.abs(forces[-1000:] - 500.0) <= 0.05 * 500.0 + 1e-6)


def test_smc_at_the_smallest_depth_reaches_only_at_eta() -> None:
    """At d = d_min (b̂/b = β) the worst-case gain of Eq. 10 just cancels the model error: ṡ = η = 0.1 N/s²."""
    regulator = ForceRegulator(ForceRegulatorConfig(law="smc", quantiser={"step_ratio": 0.0}))
    regulator.reset(1.0)
    forces = close_loop(regulator, ModelLoop(1.0, force_n=400.0), 3.0)
    assert abs(forces[-1] - forces[0]) < 1.0
    fast_config = ForceRegulatorConfig(law="smc", law_params={"eta_n_s2": 1.0e5}, quantiser={"step_ratio": 0.0})
    fast = ForceRegulator(fast_config)
    fast.reset(1.0)
    assert abs(close_loop(fast, ModelLoop(1.0, force_n=400.0), 3.0)[-1] - 500.0) <= 25.0 + 1e-6


@pytest.mark.parametrize("law", ["pi", "adaptive"])
def test_integral_laws_remove_the_offset(law: str) -> None:
    regulator = ForceRegulator(ForceRegulatorConfig(law=law, quantiser={"step_ratio": 0.0}))
    regulator.reset(1.0)
    forces = close_loop(regulator, ModelLoop(2.0, force_n=700.0), 6.0)
    assert abs(forces[-1] - 500.0) < 1.0


def test_adaptive_estimates_the_process_gain() -> None:
    regulator = ForceRegulator(ForceRegulatorConfig(law="adaptive", quantiser={"step_ratio": 0.0}))
    regulator.reset(1.0)
    close_loop(regulator, ModelLoop(2.5, force_n=500.0), 4.0)
    assert regulator.law.gain_n_per_mm == pytest.approx(1773.0 * 2.5, rel=0.02)


# ---------------------------------------------------------------- the regulator
def test_regulator_updates_once_per_period_and_applies_levels() -> None:
    regulator = ForceRegulator(ForceRegulatorConfig(law="pi", update_period_s=0.01))
    regulator.reset(1.0)
    loop, updates, applied = ModelLoop(1.0, 300.0), 0, set()
    for _ in range(100):
        sample = regulator.step(1e-3, loop.step(1e-3, regulator.last.applied_ratio), 500.0)
        updates += sample.updated
        applied.add(round(sample.applied_ratio, 9))
    assert updates == 10
    assert all(0.0 <= r <= 1.5 and abs(r * 10 - round(r * 10)) < 1e-9 for r in applied)


def test_regulator_refuses_bad_config() -> None:
    with pytest.raises(ConfigError, match="force_regulator.update_period_s must be in"):
        ForceRegulatorConfig(update_period_s=0.0)
    with pytest.raises(ConfigError, match="smc.lambda_per_s must be in"):
        ForceRegulatorConfig(law="smc", law_params={"lambda_per_s": 0.0})


# ---------------------------------------------------------------- the preview
def _replay(plan_ratios: np.ndarray, period_s: float, start_s: float, step_s: float) -> np.ndarray:
    loop, dt_s, out = ModelLoop(1.0), 1e-3, []
    for ratio in plan_ratios:
        for _ in range(int(round(period_s / dt_s))):
            loop.depth_mm = 2.0 if start_s + len(out) * dt_s >= step_s - 1e-9 else 1.0
            out.append(loop.step(dt_s, ratio))
    return np.array(out)


@pytest.mark.parametrize("quantised", [False, True])
def test_preview_plan_beats_the_feedback_floor(quantised: bool) -> None:
    switch = QuantiserConfig(step_ratio=0.1 if quantised else 0.0)
    config = PreviewConfig(before_s=0.2, after_s=0.2, sample_s=1e-3)
    plan = plan_step(MODEL, DepthSchedule([[0.0, 1.0], [1.0, 2.0]]), 1.0, 500.0, 0.01, switch, config)
    forces = _replay(plan.ratios, plan.period_s, plan.start_s, 1.0)
    assert max(forces.max() - 500.0, 0.0) == pytest.approx(plan.overshoot_n, abs=1e-3)
    assert max(500.0 - forces.min(), 0.0) == pytest.approx(plan.undershoot_n, abs=1e-3)
    assert forces.max() <= 500.0 * 1.05                        # the floor without preview is +39 %
    if quantised:
        assert np.allclose(plan.ratios * 10, np.round(plan.ratios * 10))
    assert plan.ratio_after == pytest.approx(MODEL.steady_ratio(500.0, 2.0))


def test_sigma_delta_keeps_the_running_sum_within_half_a_level() -> None:
    wanted = np.random.default_rng(5).uniform(0.0, 1.5, size=300)
    levels = sigma_delta(wanted, QuantiserConfig())
    assert np.allclose(levels * 10, np.round(levels * 10))
    assert np.max(np.abs(np.cumsum(wanted) - np.cumsum(levels))) <= 0.05 + 1e-12
