"""Incremental PID (paper 000, Eq. 14), the P law and the law registry."""
from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from cnc_contour_control.errors import ConfigError
from cnc_contour_control.laws import LAWS, FeedbackLaw, make_law, register_law
from cnc_contour_control.laws.pid import PidConfig, PidLaw


def run(law: FeedbackLaw, errors: list[float]) -> list[float]:
    return [law.step(e, 0.01) for e in errors]


@pytest.mark.parametrize(("errors", "expected"), [
    # unit step: u0 = Kp+Ki+Kd = 9.2; u1 = 9.2 + 0.1 - 6.7 = 2.6; then +Ki each sample
    ([1.0] * 5, [9.2, 2.6, 2.7, 2.8, 2.9]),
    # unit ramp 0, 1, 2, 3: 0; 2.4+0.1+6.7 = 9.2; 9.2+2.4+0.2 = 11.8; 11.8+2.4+0.3 = 14.5
    ([0.0, 1.0, 2.0, 3.0], [0.0, 9.2, 11.8, 14.5]),
    # impulse: 9.2; 9.2 - 2.4 - 13.4 = -6.6; -6.6 + 6.7 = 0.1; stays
    ([1.0, 0.0, 0.0, 0.0], [9.2, -6.6, 0.1, 0.1]),
])
def test_paper_gains_by_hand(errors: list[float], expected: list[float]) -> None:
    assert_allclose(run(make_law("pid", {}), errors), expected, rtol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-50, 50), min_size=1, max_size=30),
       st.floats(0, 5), st.floats(0, 1), st.floats(0, 10))
def test_equals_positional_form_without_clamping(errors: list[float], kp: float, ki: float,
                                                  kd: float) -> None:
    law = make_law("pid", {"kp": kp, "ki": ki, "kd": kd, "state_limit": 1e12})
    total, previous, expected = 0.0, 0.0, []
    for e in errors:
        total += e
        expected.append(kp * e + ki * total + kd * (e - previous))
        previous = e
    assert_allclose(run(law, errors), expected, rtol=1e-9, atol=1e-7)


def test_state_is_clamped_before_it_is_stored() -> None:
    law = make_law("pid", {"kp": 0.0, "ki": 1.0, "kd": 0.0, "state_limit": 10.0})
    # without the clamp the integral would wind up to 25 and need 15 samples of -1 to come back
    assert run(law, [5.0] * 5 + [-1.0, -1.0]) == [5.0, 10.0, 10.0, 10.0, 10.0, 9.0, 8.0]


def test_large_error_saturates_both_ways() -> None:
    # u0 = 920 -> 127; u1 = 127 + 0 + 10 + 6.7·(100 - 200) = -533 -> -127
    assert run(make_law("pid", {}), [100.0, 100.0]) == [127.0, -127.0]


def test_reset_clears_the_history() -> None:
    law = make_law("pid", {})
    run(law, [3.0, -2.0, 7.0])
    law.reset()
    assert run(law, [1.0, 1.0]) == pytest.approx([9.2, 2.6])


def test_p_law_is_proportional_and_stateless() -> None:
    law = make_law("p", {"kp": 3.0})
    assert run(law, [1.0, -2.0, 0.5]) == [3.0, -6.0, 1.5]
    law.reset()
    assert make_law("p", {}).step(1.0, 0.01) == 2.4


def test_laws_satisfy_the_protocol() -> None:
    for name in LAWS:
        assert isinstance(make_law(name, {}), FeedbackLaw)


def test_unknown_law_lists_valid_names() -> None:
    with pytest.raises(ConfigError) as info:
        make_law("pdd", {})
    assert f"law must be one of {sorted(LAWS)}, got 'pdd'" in str(info.value)
    assert {"p", "pid"} <= set(LAWS)


@pytest.mark.parametrize(("name", "params", "message"), [
    ("pid", {"kp": -1}, "pid.kp must be >= 0, got -1"),
    ("pid", {"ki": -0.1}, "pid.ki must be >= 0, got -0.1"),
    ("pid", {"kd": float("nan")}, "pid.kd must be finite, got nan"),
    ("pid", {"state_limit": 0}, "pid.state_limit must be > 0, got 0"),
    ("pid", {"kx": 1}, "pid.kx: unknown key; valid keys are ['kd', 'ki', 'kp', 'state_limit']"),
    ("p", {"kp": -2}, "p.kp must be >= 0, got -2"),
    ("p", {"ki": 1}, "p.ki: unknown key; valid keys are ['kp']"),
])
def test_bad_params_name_option_bound_value(name: str, params: dict, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        make_law(name, params)
    assert message in str(info.value)


def test_register_law_adds_and_refuses_duplicates() -> None:
    @register_law("test_zero")
    def make_zero(params: object) -> PidLaw:
        return PidLaw(PidConfig(kp=0.0, ki=0.0, kd=0.0))

    try:
        assert make_law("test_zero", {}).step(5.0, 0.01) == 0.0
        with pytest.raises(ValueError, match="already registered"):
            register_law("test_zero")(make_zero)
    finally:
        del LAWS["test_zero"]
