"""Core maths tests of the fuzzy servo law of paper 000 (no ROS)."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.laws import LAWS, FeedbackLaw, LawSample, make_law
from cnc_contour_control.laws.fuzzy import (
    PAPER000_DE_CENTRES_PER_SAMPLE,
    PAPER000_SAMPLE_TIME_S,
    RULE_BASES,
    SET_NAMES,
    FuzzyConfig,
    FuzzyLaw,
    FuzzySurface,
    fuzzy_params_from_per_sample,
    memberships,
)
from cnc_contour_control.laws.fuzzy_gains import TABLE4_GAINS, equivalent_gains, format_gains_table

E_C = (-21.0, -14.0, -7.0, 0.0, 7.0, 14.0, 21.0)
DE_C = (-450.0, -300.0, -150.0, 0.0, 150.0, 300.0, 450.0)  # Table 3's BLU per sample / 10 ms
U_C = (-55.0, -35.0, -15.0, 0.0, 15.0, 35.0, 55.0)
#: A diagonal (MacVicar-Whelan) rule base: C_ij = set i + j - 3, saturated.
PAPER = RULE_BASES["paper000"]
DIAGONAL = tuple(tuple(SET_NAMES[min(6, max(0, i + j - 3))] for j in range(7)) for i in range(7))

huge = st.floats(min_value=-1e300, max_value=1e300, allow_nan=False)
wide = st.one_of(st.floats(min_value=-30.0, max_value=30.0), huge)


def pd_law(**params: object) -> FuzzyLaw:
    """A fuzzy law without the integral term."""
    return FuzzyLaw(FuzzyConfig(ki=0.0, **params))  # type: ignore[arg-type]  # FuzzyConfig's own keywords


def step(law: FuzzyLaw, error: float, dt_s: float = 0.01) -> float:
    """One law step on ``error`` [BLU] over ``dt_s``; the feedback [DAC]."""
    return law.step(LawSample(dt_s=dt_s, error_counts=error)).feedback


def law_output(law: FuzzyLaw, e: float, de: float) -> float:
    """Drive ``law`` to the state e(k) = e, e(k-1) = e - de over 1 s (rate = change) and return u(k)."""
    law.reset()
    step(law, e - de, 1.0)
    return step(law, e, 1.0)


# --- membership functions ---------------------------------------------------------------


@pytest.mark.parametrize("centres", [E_C, DE_C, U_C, (-3.0, -1.0, -0.5, 0.0, 0.2, 2.0, 9.0)])
@pytest.mark.parametrize("fraction", [0.0, 0.013, 0.25, 0.5, 0.77, 0.999, 1.0])
def test_memberships_are_a_partition_of_unity_within_the_centres(centres, fraction):
    x = centres[0] + fraction * (centres[-1] - centres[0])
    degrees = memberships(x, centres)
    assert math.fsum(degrees) == pytest.approx(1.0, abs=1e-12)
    active = [k for k, d in enumerate(degrees) if d > 0.0]
    assert 1 <= len(active) <= 2
    assert active[-1] - active[0] <= 1


@pytest.mark.parametrize("k", range(7))
def test_membership_is_one_at_its_centre(k):
    degrees = memberships(E_C[k], E_C)
    assert degrees[k] == 1.0
    assert math.fsum(degrees) == 1.0


@pytest.mark.parametrize(
    "x, expected", [(-1e300, 0), (-21.5, 0), (21.01, 6), (1e300, 6), (math.inf, 6)]
)
def test_memberships_saturate_at_the_shoulders(x, expected):
    degrees = memberships(x, E_C)
    assert degrees[expected] == 1.0
    assert math.fsum(degrees) == 1.0


# --- the map F ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(RULE_BASES))
def test_output_at_the_centres_is_the_rule_output_centre(name):
    config = FuzzyConfig(rule_base=name, ki=0.0)
    surface, law = FuzzySurface(config), FuzzyLaw(config)
    table = config.output_table()
    for i, e in enumerate(E_C):
        for j, de in enumerate(DE_C):
            assert surface(e, de) == pytest.approx(table[i][j], abs=1e-12)
            assert law_output(law, e, de) == pytest.approx(table[i][j], abs=1e-12)


def test_output_table_maps_names_to_centres():
    table = FuzzyConfig().output_table()
    assert table[4] == (0.0, 15.0, 15.0, 15.0, 35.0, 35.0, 55.0)
    assert table[0] == (-55.0,) * 7


@pytest.mark.parametrize(
    "e, de, expected",
    [
        (1e6, 0.0, 55.0),
        (-1e300, -1e300, -55.0),
        (math.inf, -math.inf, 55.0),
        (21.0 + 1e-9, 450.0 + 1e-9, 55.0),
        (7.0, 1e9, 55.0),  # PS row, de = PL
        (7.0, -1e9, 0.0),  # PS row, de = NL
        (-7.0, 1e9, 0.0),
    ],
)
def test_inputs_outside_the_centres_saturate(e, de, expected):
    assert FuzzySurface(FuzzyConfig())(e, de) == expected


def test_scales_are_applied_to_inputs_and_output():
    plain = FuzzySurface(FuzzyConfig())
    scaled = FuzzySurface(FuzzyConfig(e_scale=2.0, de_scale=0.5, u_scale=3.0))
    for e, de in [(1.3, 0.2), (-5.0, 2.9), (8.8, -1.1), (40.0, 40.0)]:
        assert scaled(e, de) == pytest.approx(3.0 * plain(2.0 * e, 0.5 * de), abs=1e-9)


@settings(max_examples=300, deadline=None)
@given(
    e=wide,
    de=wide,
    u_scale=st.floats(min_value=0.01, max_value=100.0),
    name=st.sampled_from(sorted(RULE_BASES)),
)
def test_output_is_finite_and_bounded(e, de, u_scale, name):
    law = pd_law(rule_base=name, u_scale=u_scale)
    u = law_output(law, e, de)
    assert math.isfinite(u)
    assert u_scale * min(U_C) - 1e-9 <= u <= u_scale * max(U_C) + 1e-9


@settings(max_examples=300, deadline=None)
@given(e1=wide, e2=wide, de=wide, name=st.sampled_from(sorted(RULE_BASES)))
def test_output_is_non_decreasing_in_e(e1, e2, de, name):
    surface = FuzzySurface(FuzzyConfig(rule_base=name))
    low, high = sorted((e1, e2))
    assert surface(low, de) <= surface(high, de) + 1e-9


@settings(max_examples=300, deadline=None)
@given(e=wide, de1=wide, de2=wide)
def test_output_is_non_decreasing_in_de_for_a_diagonal_rule_base(e, de1, de2):
    surface = FuzzySurface(FuzzyConfig(rule_base=DIAGONAL))
    low, high = sorted((de1, de2))
    assert surface(e, low) <= surface(e, high) + 1e-9


@settings(max_examples=200, deadline=None)
@given(i=st.integers(0, 6), de1=wide, de2=wide, name=st.sampled_from(sorted(RULE_BASES)))
def test_output_is_non_decreasing_in_de_on_the_error_centres(i, de1, de2, name):
    surface = FuzzySurface(FuzzyConfig(rule_base=name))
    low, high = sorted((de1, de2))
    assert surface(E_C[i], low) <= surface(E_C[i], high) + 1e-9


def test_min_inference_is_not_monotone_in_de_between_error_centres():
    """Documented property of Mamdani min + Eq. 8, not a bug (docs/fuzzy_rule_base.md).

    At e = -19.55 (NL 0.79, NM 0.21) and de = 180 BLU/s (PS 0.8, PM 0.2) both
    NM-row rules (output NS) fire with weight ~0.2; at de = 300 only one does,
    so the NL rules weigh more and F falls by 3.3 DAC although de rose.
    """
    surface = FuzzySurface(FuzzyConfig())
    assert surface(-19.55, 180.0) == pytest.approx(-43.37, abs=0.01)
    assert surface(-19.55, 300.0) == pytest.approx(-46.71, abs=0.01)


@settings(max_examples=200, deadline=None)
@given(e=wide, de=wide)
def test_paper000_rule_base_is_odd_symmetric(e, de):
    surface = FuzzySurface(FuzzyConfig())
    assert surface(-e, -de) == pytest.approx(-surface(e, de), abs=1e-9)


# --- the law --------------------------------------------------------------------------


@settings(max_examples=300, deadline=None)
@given(errors=st.lists(wide, min_size=1, max_size=8), name=st.sampled_from(sorted(RULE_BASES)))
def test_law_step_equals_surface_plus_integral(errors, name):
    config = FuzzyConfig(
        rule_base=name, e_scale=1.5, de_scale=0.7, u_scale=1.2, ki=0.3, integral_limit=40.0
    )
    law, surface = FuzzyLaw(config), FuzzySurface(config)
    previous, integral, dt_s = 0.0, 0.0, 0.004
    for error in errors:
        integral = min(40.0, max(-40.0, integral + 0.3 * dt_s * error))
        expected = surface(error, (error - previous) / dt_s) + integral
        assert step(law, error, dt_s) == pytest.approx(expected, rel=1e-12, abs=1e-9)
        assert law.integral == pytest.approx(integral)
        previous = error


def test_integral_accumulates_and_is_clamped():
    law = FuzzyLaw(FuzzyConfig(ki=100.0, integral_limit=5.0))  # ki·T = 1 at T = 10 ms
    integrals = []
    for _ in range(4):
        step(law, 2.0)
        integrals.append(law.integral)
    assert integrals == [2.0, 4.0, 5.0, 5.0]
    for _ in range(20):
        step(law, -3.0)
    assert law.integral == -5.0
    law.reset()
    assert law.integral == 0.0


def test_zero_integral_limit_disables_the_integral():
    law = FuzzyLaw(FuzzyConfig(ki=0.5, integral_limit=0.0))
    for error in (3.0, 9.0, -2.0):
        step(law, error)
        assert law.integral == 0.0


def test_first_step_after_reset_uses_zero_previous_error():
    law = pd_law()
    step(law, 10.0)
    law.reset()
    assert step(law, 7.0) == FuzzySurface(FuzzyConfig())(7.0, 700.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_error_is_a_fault_and_keeps_the_state(bad):
    law = FuzzyLaw(FuzzyConfig())
    step(law, 3.0)
    before = law.integral
    with pytest.raises(FaultError, match="error must be finite"):
        step(law, bad)
    assert law.integral == before


def test_fuzzy_is_registered():
    law = make_law("fuzzy", {"rule_base": "paper000_alt_a", "ki": 0.2})
    assert "fuzzy" in LAWS
    assert isinstance(law, FuzzyLaw)
    assert isinstance(law, FeedbackLaw)
    assert law.config.ki == 0.2


def test_unknown_key_lists_valid_keys():
    with pytest.raises(ConfigError, match=r"fuzzy\.kp: unknown key.*'integral_limit'"):
        make_law("fuzzy", {"kp": 2.4})


# --- configuration errors ---------------------------------------------------------------


def test_rule_base_from_yaml_lists_is_normalised():
    rows = [list(row) for row in RULE_BASES["paper000"]]
    config = FuzzyConfig(rule_base=rows, e_centres=list(E_C))  # type: ignore[arg-type]  # lists on purpose (as from YAML)
    assert config.rule_base == RULE_BASES["paper000"]
    assert config.e_centres == E_C
    assert config == FuzzyConfig()


@pytest.mark.parametrize(
    "rule_base, message",
    [
        ("paper999", r"rule_base must be one of \['paper000'.*got 'paper999'"),
        (RULE_BASES["paper000"][:6], "rule_base must have 7 rows .*got 6"),
        (42, "rule_base must have 7 rows .*got int"),
        (PAPER[:2] + (("NL",) * 6,) + PAPER[3:], r"row 2 \(e = NS\) must have 7 entries .*got 6"),
        (PAPER[:4] + ("PS PS PS PM PM PL PL",) + PAPER[5:], r"row 4 \(e = PS\)"),
    ],
)
def test_bad_rule_base_shape_is_named(rule_base, message):
    with pytest.raises(ConfigError, match=message):
        FuzzyConfig(rule_base=rule_base)


def test_unknown_set_name_names_the_entry_and_the_valid_names():
    rows = [list(row) for row in RULE_BASES["paper000"]]
    rows[1][3] = "XL"
    with pytest.raises(ConfigError) as info:
        FuzzyConfig(rule_base=rows)  # type: ignore[arg-type]  # lists on purpose (as from YAML)
    text = str(info.value)
    assert "rule_base[1][3] (e = NM, de = ZR)" in text
    assert "'XL'" in text
    assert "['NL', 'NM', 'NS', 'ZR', 'PS', 'PM', 'PL']" in text


@pytest.mark.parametrize("key", ["e_centres", "de_centres", "u_centres"])
def test_centres_must_increase_strictly(key):
    centres = list(E_C)
    centres[4] = centres[3]
    message = rf"{key} must be strictly increasing: {key}\[4\] = 0.0 must be > {key}\[3\] = 0.0"
    with pytest.raises(ConfigError, match=message):
        FuzzyConfig(**{key: centres})


@pytest.mark.parametrize(
    "params, message",
    [
        ({"e_centres": (1.0, 2.0, 3.0)}, r"e_centres must have 7 values"),
        ({"de_centres": "abcdefg"}, r"de_centres must have 7 values"),
        ({"u_centres": (0, 1, 2, math.nan, 4, 5, 6)}, r"u_centres\[3\] must be finite"),
        ({"e_scale": 0.0}, r"fuzzy\.e_scale must be in \[1e-09, 1000000000\.0\], got 0\.0"),
        ({"u_scale": -1.0}, r"u_scale must be in \[1e-09, 1000000000\.0\], got -1\.0"),
        ({"ki": -0.1}, r"ki must be in \[0\.0, 1000000\.0\], got -0\.1"),
        ({"integral_limit": math.inf}, "integral_limit must be finite"),
    ],
)
def test_bad_numbers_are_named(params, message):
    with pytest.raises(ConfigError, match=message):
        FuzzyConfig(**params)


# --- equivalent gains (Eqs. 11-13) ---------------------------------------------------------


def test_equivalent_gains_of_paper000_round_to_table4():
    gains = equivalent_gains(FuzzyConfig())
    per_sample = gains.per_sample(0.01)
    assert per_sample["kp"] == gains.kp == pytest.approx(TABLE4_GAINS["kp"], abs=0.05)
    assert per_sample["kd"] == pytest.approx(TABLE4_GAINS["kd"], abs=0.05)
    assert per_sample["ki"] == pytest.approx(TABLE4_GAINS["ki"], rel=1e-12)
    assert (gains.kd, gains.ki) == pytest.approx((0.0667, 10.0), abs=1e-4)  # seconds, per second
    assert gains.k2_min == 0.0
    assert (gains.k1_min, gains.k1_max, gains.k2_max) == pytest.approx((15 / 7, 55 / 21, 20 / 150))


def test_sector_bounds_match_finite_differences_of_the_law_near_the_origin():
    """K1_min is dF/de at the origin, K1_max the secant to PL, K2_max dF/dde next to e = PS."""
    gains = equivalent_gains(FuzzyConfig())
    law, h = pd_law(), 1e-4
    slope_e_at_origin = (law_output(law, h, 0.0) - law_output(law, 0.0, 0.0)) / h
    secant_to_pl = law_output(law, 21.0, 0.0) / 21.0
    slope_de_at_ps = (law_output(law, 7.0, h) - law_output(law, 7.0, 0.0)) / h
    slope_de_at_origin = (law_output(law, 0.0, h) - law_output(law, 0.0, -h)) / (2 * h)
    assert gains.k1_min == pytest.approx(slope_e_at_origin, rel=1e-6)
    assert gains.k1_max == pytest.approx(secant_to_pl, rel=1e-6)
    assert gains.k2_max == pytest.approx(slope_de_at_ps, rel=1e-6)
    assert slope_de_at_origin == 0.0  # the ZR row: no D action at e = 0


@pytest.mark.parametrize(
    "params, kp_factor, kd_factor",
    [({"e_scale": 2.0}, 2.0, 1.0), ({"de_scale": 3.0}, 1.0, 3.0), ({"u_scale": 0.5}, 0.5, 0.5)],
)
def test_equivalent_gains_follow_the_scales(params, kp_factor, kd_factor):
    base = equivalent_gains(FuzzyConfig())
    scaled = equivalent_gains(FuzzyConfig(**params))
    assert scaled.kp == pytest.approx(kp_factor * base.kp)
    assert scaled.kd == pytest.approx(kd_factor * base.kd)


# --- the gains table ---------------------------------------------------------------------


def test_gains_table_is_printed_beside_table4():
    out = format_gains_table()
    assert "Table 4 (paper)    2.40   0.10   6.70" in out
    assert "paper000           2.38   0.10   6.67" in out


# --- time units ----------------------------------------------------------------------------


def test_paper_per_sample_values_convert_to_the_defaults():
    paper = {"de_centres": PAPER000_DE_CENTRES_PER_SAMPLE, "ki": 0.1, "e_scale": 2.0}
    converted = fuzzy_params_from_per_sample(paper, PAPER000_SAMPLE_TIME_S)
    assert converted["de_centres"] == pytest.approx(FuzzyConfig().de_centres)
    assert converted["ki"] == pytest.approx(FuzzyConfig().ki)
    assert converted["e_scale"] == 2.0
    with pytest.raises(ConfigError, match="sample_time_s must be > 0"):
        fuzzy_params_from_per_sample(paper, -0.01)


@pytest.mark.parametrize("dt_s", [0.01, 0.001])
def test_same_error_signal_same_output_at_any_period(dt_s):
    """e(t) = 300·t (a rate of 300 BLU/s): the same output at t = 0.05 s whatever the period."""
    law = FuzzyLaw(FuzzyConfig(ki=0.0))
    n = round(0.05 / dt_s)
    outputs = [step(law, 300.0 * k * dt_s, dt_s) for k in range(1, n + 1)]
    assert outputs[-1] == pytest.approx(FuzzySurface(FuzzyConfig())(15.0, 300.0), rel=1e-9)


def test_retune_swaps_the_map_and_keeps_the_state():
    law, twin = FuzzyLaw(FuzzyConfig()), FuzzyLaw(FuzzyConfig(u_scale=2.0))
    for error in (3.0, 5.0):
        step(law, error)
        step(twin, error)
    law.retune(FuzzyConfig(u_scale=2.0))
    assert law.integral == twin.integral
    assert step(law, 6.0) == step(twin, 6.0)  # e(k-1) and u_I kept: as if tuned so from the start
    law.retune(FuzzyConfig(integral_limit=0.1))
    assert law.integral == 0.1  # the integral is clamped to the new limit
    with pytest.raises(ConfigError, match="fuzzy law needs a FuzzyConfig to retune"):
        law.retune({"ki": 1.0})
