"""Incremental PID (paper 000, Eq. 14) in time units, the P law, the law seam and the law registry."""
from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import param_specs
from cnc_contour_control.laws import LAWS, FeedbackLaw, LawEntry, LawSample, law_config_class, make_law
from cnc_contour_control.laws.pid import PidConfig, PidLaw, pid_gains_from_per_sample, pid_gains_per_sample

#: Table 4 of paper 000 (per sample at T = 10 ms) in time units.
TABLE4 = {"kp": 2.4, "ki": 10.0, "kd": 0.067}


def run(law: FeedbackLaw, errors: list[float], dt_s: float | list[float] = 0.01) -> list[float]:
    periods = dt_s if isinstance(dt_s, list) else [dt_s] * len(errors)
    sample = LawSample()
    out = []
    for e, dt in zip(errors, periods):
        sample.error_counts, sample.dt_s = e, dt
        out.append(law.step(sample).feedback)
    return out


@pytest.mark.parametrize(("errors", "expected"), [
    # unit step: u0 = Kp+Ki+Kd = 9.2; u1 = 9.2 + 0.1 - 6.7 = 2.6; then +Ki each sample
    ([1.0] * 5, [9.2, 2.6, 2.7, 2.8, 2.9]),
    # unit ramp 0, 1, 2, 3: 0; 2.4+0.1+6.7 = 9.2; 9.2+2.4+0.2 = 11.8; 11.8+2.4+0.3 = 14.5
    ([0.0, 1.0, 2.0, 3.0], [0.0, 9.2, 11.8, 14.5]),
    # impulse: 9.2; 9.2 - 2.4 - 13.4 = -6.6; -6.6 + 6.7 = 0.1; stays
    ([1.0, 0.0, 0.0, 0.0], [9.2, -6.6, 0.1, 0.1]),
])
def test_paper_gains_by_hand_at_10ms(errors: list[float], expected: list[float]) -> None:
    assert make_law("pid", {}).config == PidConfig(**TABLE4)
    assert_allclose(run(make_law("pid", {}), errors), expected, rtol=1e-12)


def test_table4_conversion_both_ways() -> None:
    assert pid_gains_from_per_sample(2.4, 0.1, 6.7, 0.01) == pytest.approx(TABLE4, rel=1e-15)
    assert pid_gains_per_sample(**TABLE4, sample_time_s=0.01) == pytest.approx({"kp": 2.4, "ki": 0.1, "kd": 6.7})
    with pytest.raises(ConfigError, match="sample_time_s must be > 0, got 0"):
        pid_gains_from_per_sample(2.4, 0.1, 6.7, 0)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-50, 50), min_size=1, max_size=30),
       st.floats(0, 5), st.floats(0, 100), st.floats(0, 0.1), st.sampled_from([0.01, 0.001, 0.0037]))
def test_equals_positional_form_without_clamping(errors: list[float], kp: float, ki: float,
                                                  kd: float, dt_s: float) -> None:
    law = make_law("pid", {"kp": kp, "ki": ki, "kd": kd, "state_limit": 1e12})
    total, previous, expected = 0.0, 0.0, []
    for e in errors:
        total += e * dt_s
        expected.append(kp * e + ki * total + kd * (e - previous) / dt_s)
        previous = e
    assert_allclose(run(law, errors, dt_s), expected, rtol=1e-9, atol=1e-6)


def test_another_period_keeps_the_continuous_loop() -> None:
    """A ramp of 1 count/s: the D term gives kd·1 whatever T, the I term ki·∫e whatever T."""
    for dt_s in (0.01, 0.001):
        n = round(0.5 / dt_s)
        errors = [k * dt_s for k in range(1, n + 1)]  # e(t) = t
        u = run(make_law("pid", {"kp": 0.0, "ki": 4.0, "kd": 0.5, "state_limit": 1e9}), errors, dt_s)
        # u(t) = ki ∫ e + kd de/dt ≈ 4·t²/2 + 0.5 (rectangle rule: + ki·t·T/2)
        assert u[-1] == pytest.approx(4.0 * 0.5**2 / 2 + 0.5 + 4.0 * 0.5 * dt_s / 2, rel=1e-9)


def test_varying_period_uses_each_sample_dt() -> None:
    law = make_law("pid", {"kp": 0.0, "ki": 0.0, "kd": 1.0, "state_limit": 1e9})
    # e = 1 after 0.01 s (rate 100), then 2 after 0.02 s (rate 50): u = 100, then 100 + (50 - 100)
    assert run(law, [1.0, 2.0], [0.01, 0.02]) == pytest.approx([100.0, 50.0])


def test_state_is_clamped_before_it_is_stored() -> None:
    law = make_law("pid", {"kp": 0.0, "ki": 100.0, "kd": 0.0, "state_limit": 10.0})
    # ki·T = 1: without the clamp the integral would wind up to 25 and need 15 samples of -1 to come back
    assert run(law, [5.0] * 5 + [-1.0, -1.0]) == pytest.approx([5.0, 10.0, 10.0, 10.0, 10.0, 9.0, 8.0])


def test_large_error_saturates_both_ways() -> None:
    # u0 = 920 -> 127; u1 = 127 + 0 + 10 + 6.7·(100 - 200) = -533 -> -127
    assert run(make_law("pid", {}), [100.0, 100.0]) == [127.0, -127.0]


def test_reset_clears_the_history() -> None:
    law = make_law("pid", {})
    run(law, [3.0, -2.0, 7.0])
    law.reset()
    assert run(law, [1.0, 1.0]) == pytest.approx([9.2, 2.6])


def test_retune_swaps_gains_and_keeps_the_state() -> None:
    law, twin = make_law("pid", {}), make_law("pid", {})
    run(law, [1.0, 2.0])
    run(twin, [1.0, 2.0])
    law.retune(PidConfig(kp=4.0, ki=10.0, kd=0.067))
    [got] = run(law, [2.0])
    [same_gains] = run(twin, [2.0])
    assert got == pytest.approx(same_gains)  # the kp change acts on e(k) - e(k-1) = 0 only
    assert run(law, [3.0]) == pytest.approx([got + 4.0 + 0.3 + 6.7])
    with pytest.raises(ConfigError, match="pid law needs a PidConfig to retune, got dict"):
        law.retune({"kp": 1.0})  # type: ignore[arg-type]  # a dict on purpose: refused


def test_p_law_is_proportional_and_stateless() -> None:
    law = make_law("p", {"kp": 3.0})
    assert run(law, [1.0, -2.0, 0.5]) == [3.0, -6.0, 1.5]
    law.reset()
    law.retune(law_config_class("p")(kp=1.0))
    assert run(law, [2.0]) == [2.0]
    assert run(make_law("p", {}), [1.0]) == [2.4]


def test_laws_satisfy_the_protocol_and_answer_with_an_output() -> None:
    for name in LAWS:
        law = make_law(name, {})
        assert isinstance(law, FeedbackLaw)
        out = law.step(LawSample(dt_s=getattr(law, "sample_time_s", 0.01), error_counts=1.0))  # a designed law's period
        assert out.disturbance_estimate == 0.0 and out.feedback > 0.0


def test_law_config_classes_declare_every_field() -> None:
    for name, entry in LAWS.items():
        assert law_config_class(name) is entry.config_class
        for spec in param_specs(entry.config_class):
            assert spec.info.description, f"{name}.{spec.name} has no description"
            if spec.kind is float:
                assert spec.info.low is not None and spec.info.high is not None, f"{name}.{spec.name}"


@pytest.mark.parametrize("name", sorted(LAWS))
def test_declared_ranges_are_the_validation(name: str) -> None:
    """At each bound a config is accepted; just beyond it, refused naming the field and the range."""
    cls = law_config_class(name)
    for spec in param_specs(cls):
        if spec.kind is not float:
            continue
        for bound, beyond in ((spec.info.low, -1.0), (spec.info.high, 1.0)):
            assert dataclasses.replace(cls(), **{spec.name: bound}) is not None
            outside = bound + beyond * max(1.0, abs(bound)) * 1e-3
            with pytest.raises(ConfigError, match=f"{name}.{spec.name} must be in"):
                cls(**{spec.name: outside})


def test_unknown_law_lists_valid_names() -> None:
    for call in (lambda: make_law("pdd", {}), lambda: law_config_class("pdd")):
        with pytest.raises(ConfigError) as info:
            call()
        assert f"law must be one of {sorted(LAWS)}, got 'pdd'" in str(info.value)
    assert {"p", "pid", "fuzzy"} <= set(LAWS)


@pytest.mark.parametrize(("name", "params", "message"), [
    ("pid", {"kp": -1}, "pid.kp must be in [0.0, 1000000.0], got -1"),
    ("pid", {"ki": -0.1}, "pid.ki must be in [0.0, 1000000.0], got -0.1"),
    ("pid", {"kd": float("nan")}, "pid.kd must be finite, got nan"),
    ("pid", {"kd": "fast"}, "pid.kd must be a number, got 'fast'"),
    ("pid", {"state_limit": 0}, "pid.state_limit must be in [1e-09, 1000000000000.0], got 0"),
    ("pid", {"kx": 1}, "pid.kx: unknown key; valid keys are ['kd', 'ki', 'kp', 'state_limit']"),
    ("p", {"kp": -2}, "p.kp must be in [0.0, 1000000.0], got -2"),
    ("p", {"ki": 1}, "p.ki: unknown key; valid keys are ['kp']"),
])
def test_bad_params_name_option_bound_value(name: str, params: dict, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        make_law(name, params)
    assert message in str(info.value)


def test_a_law_added_to_the_registry_is_built_by_name() -> None:
    LAWS["test_zero"] = LawEntry(PidConfig, lambda config: PidLaw(dataclasses.replace(config, kp=0.0, ki=0.0, kd=0.0)))
    try:
        assert run(make_law("test_zero", {}), [5.0]) == [0.0]
        assert law_config_class("test_zero") is PidConfig
    finally:
        del LAWS["test_zero"]
