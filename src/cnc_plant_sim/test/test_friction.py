"""Friction models: paper 000 Eq. (15) golden values, the registry, tables, validation."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError
from cnc_plant_sim.models.friction import (
    FRICTIONS,
    CoulombViscousFriction,
    TableFriction,
    make_friction,
)

# Eq. (15) evaluated by hand: (model, V [mm/s], F [DAC]).
GOLDEN = [
    ("paper000_x", 0.0, 20.49),
    ("paper000_x", 5.0, 0.05 * 25 - 1.16 * 5 + 20.49),  # 15.94
    ("paper000_x", 10.0, 13.89),
    ("paper000_x", 11.999, 0.05 * 11.999**2 - 1.16 * 11.999 + 20.49),
    ("paper000_x", 12.0, 13.95),
    ("paper000_x", 40.0, 13.95),
    ("paper000_x", -5.0, -14.27),
    ("paper000_x", -12.0, -12.03),
    ("paper000_x", -12.001, -11.84),
    ("paper000_x", -40.0, -11.84),
    ("paper000_y", 0.0, 19.99),
    ("paper000_y", 5.0, 15.39),
    ("paper000_y", 12.0, 12.76),
    ("paper000_y", -5.0, -13.94),
    ("paper000_y", -12.0, -11.56),
    ("paper000_y", -20.0, -11.80),
]


@pytest.mark.parametrize(("name", "velocity_mm_s", "force_dac"), GOLDEN)
def test_eq15_golden_values(name: str, velocity_mm_s: float, force_dac: float) -> None:
    assert_allclose(make_friction(name).force(velocity_mm_s), force_dac, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("name", "positive", "negative"),
                         [("paper000_x", 20.49, -18.27), ("paper000_y", 19.99, -16.84)])
def test_eq15_breakaway_is_branch_value_at_zero(name: str, positive: float, negative: float) -> None:
    model = make_friction(name)
    assert_allclose([model.breakaway_positive, model.breakaway_negative], [positive, negative])
    assert_allclose(model.force(-1e-12), negative, atol=1e-9)


@pytest.mark.parametrize("scale", [0.92, 1.0, 1.08])
def test_scale_multiplies_force_and_breakaway(scale: float) -> None:
    model = make_friction("paper000_x", {"scale": scale})
    assert_allclose(model.force(5.0), 15.94 * scale)
    assert_allclose(model.breakaway_negative, -18.27 * scale)
    assert_allclose(make_friction("paper000_x").scaled(scale).force(-5.0), -14.27 * scale)


SLOPE_CASES = [
    ("paper000_x", {}, 5.0),
    ("paper000_x", {}, -7.0),
    ("paper000_y", {"scale": 1.05}, 3.0),
    ("coulomb_viscous", {"coulomb_dac": 10, "viscous_dac_per_mm_s": 0.5,
                         "static_dac": 15, "stribeck_velocity_mm_s": 2}, 1.5),
    ("coulomb_viscous", {"coulomb_dac": 10, "viscous_dac_per_mm_s": 0.5,
                         "static_dac": 15, "stribeck_velocity_mm_s": 2}, -3.0),
    ("table", {"velocity_mm_s": [-10, -2, 2, 10], "force_dac": [-12, -15, 16, 13]}, 4.0),
    ("none", {}, 3.0),
]


@pytest.mark.parametrize(("name", "params", "velocity_mm_s"), SLOPE_CASES)
def test_linearise_slope_matches_finite_difference(name: str, params: dict, velocity_mm_s: float) -> None:
    model = make_friction(name, params)
    direction = 1 if velocity_mm_s >= 0 else -1
    force, slope = model.linearise(velocity_mm_s, direction)
    delta = 1e-6
    numeric = (model.force(velocity_mm_s + delta) - model.force(velocity_mm_s - delta)) / (2 * delta)
    assert_allclose(force, model.force(velocity_mm_s))
    assert_allclose(slope, numeric, rtol=1e-6, atol=1e-8)


def test_coulomb_viscous_stribeck() -> None:
    model = make_friction("coulomb_viscous", {"coulomb_dac": 10, "viscous_dac_per_mm_s": 0.5,
                                              "static_dac": 15, "stribeck_velocity_mm_s": 2})
    assert_allclose(model.force(2.0), 10 + 5 * math.exp(-1) + 1.0)
    assert_allclose(model.force(-2.0), -(10 + 5 * math.exp(-1)) - 1.0)
    assert (model.breakaway_positive, model.breakaway_negative) == (15.0, -15.0)


def test_coulomb_viscous_static_defaults_to_coulomb() -> None:
    model = CoulombViscousFriction(coulomb_dac=7.0)
    assert model.static_dac == 7.0
    assert (model.breakaway_positive, model.force(3.0), model.force(-3.0)) == (7.0, 7.0, -7.0)


def test_none_has_no_friction() -> None:
    model = make_friction("none")
    assert (model.force(5.0), model.breakaway_positive, model.breakaway_negative) == (0.0, 0.0, 0.0)


class TestTable:
    V = [-10.0, -2.0, 2.0, 10.0]
    F = [-12.0, -15.0, 16.0, 13.0]

    @pytest.mark.parametrize(("velocity_mm_s", "force_dac"), [
        (6.0, 14.5), (2.0, 16.0), (1.0, 16.0), (0.0, 16.0), (50.0, 13.0),
        (-6.0, -13.5), (-1.0, -15.0), (-50.0, -12.0),
    ])
    def test_interpolates_per_branch(self, velocity_mm_s: float, force_dac: float) -> None:
        model = TableFriction.from_arrays(self.V, self.F)
        assert_allclose(model.force(velocity_mm_s), force_dac)

    def test_breakaway_defaults_and_explicit(self) -> None:
        model = TableFriction.from_arrays(self.V, self.F)
        assert (model.breakaway_positive, model.breakaway_negative) == (16.0, -15.0)
        model = TableFriction.from_arrays(self.V, self.F, 20.0, -18.0)
        assert (model.breakaway_positive, model.breakaway_negative) == (20.0, -18.0)
        assert model.force(1.0) == 16.0

    def test_from_arrays_sorts(self) -> None:
        order = [2, 0, 3, 1]
        model = TableFriction.from_arrays(np.array(self.V)[order], np.array(self.F)[order])
        assert model.velocity_mm_s == tuple(self.V)
        assert model.force_dac == tuple(self.F)

    def test_round_trip_through_params(self) -> None:
        model = TableFriction.from_arrays(self.V, self.F, 20.0, -18.0, scale=1.05)
        rebuilt = make_friction("table", model.to_params())
        assert rebuilt == model
        assert_allclose(rebuilt.force(6.0), model.force(6.0))

    @pytest.mark.parametrize(("params", "message"), [
        ({"velocity_mm_s": [1, 0, 2], "force_dac": [1, 2, 3]},
         "velocity_mm_s must be strictly increasing, got 0.0 after 1.0"),
        ({"velocity_mm_s": [-1, 1], "force_dac": [1]},
         "force_dac must have the length of velocity_mm_s (2), got 1"),
        ({"velocity_mm_s": [1, 2], "force_dac": [1, 2]}, "needs a point <= 0"),
        ({"velocity_mm_s": [-2, -1], "force_dac": [1, 2]}, "needs a point >= 0"),
        ({"velocity_mm_s": [-1, 1], "force_dac": [-1, 1], "breakaway_positive_dac": -5},
         "breakaway_negative_dac must be <= breakaway_positive_dac (-5.0), got -1.0"),
        ({"velocity_mm_s": [-1, float("nan")], "force_dac": [-1, 1]},
         "velocity_mm_s must be finite, got nan"),
    ])
    def test_bad_tables(self, params: dict, message: str) -> None:
        with pytest.raises(ConfigError) as info:
            make_friction("table", params)
        assert message in str(info.value)

    @settings(max_examples=50, deadline=None)
    @given(st.lists(st.floats(-50, 50), min_size=1, max_size=20))
    def test_within_point_range(self, velocities: list[float]) -> None:
        model = TableFriction.from_arrays(self.V, self.F)
        forces = [model.force(v) for v in velocities]
        assert all(-15.0 <= f <= -12.0 or 13.0 <= f <= 16.0 for f in forces)


def test_unknown_friction_lists_valid_names() -> None:
    with pytest.raises(ConfigError) as info:
        make_friction("stribeck")
    for name in FRICTIONS:
        assert name in str(info.value)
    assert "'stribeck'" in str(info.value)


@pytest.mark.parametrize(("name", "params", "message"), [
    ("paper000_x", {"scael": 1.0}, "paper000_x.scael: unknown key; valid keys are ['scale']"),
    ("coulomb_viscous", {"viscous": 1.0}, "coulomb_viscous.viscous: unknown key"),
    ("paper000_y", {"scale": -0.1}, "scale must be >= 0, got -0.1"),
    ("coulomb_viscous", {"coulomb_dac": -1}, "coulomb_dac must be >= 0, got -1"),
    ("coulomb_viscous", {"viscous_dac_per_mm_s": -2}, "viscous_dac_per_mm_s must be >= 0, got -2"),
    ("coulomb_viscous", {"static_dac": -3}, "static_dac must be >= 0, got -3"),
    ("coulomb_viscous", {"stribeck_velocity_mm_s": -1}, "stribeck_velocity_mm_s must be >= 0, got -1"),
    ("none", {"scale": float("inf")}, "scale must be finite, got inf"),
])
def test_bad_params_name_option_bound_value(name: str, params: dict, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        make_friction(name, params)
    assert message in str(info.value)
