"""Paper 001's mass-friction plant: stiction, Stribeck, steady state, the ODE, faults, config, registry, node."""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_plant_sim.models.mass_friction import (
    CUTTING_LOADS,
    PAPER001_AXES,
    MassFrictionOptions,
    MassFrictionPlant,
    axis_params,
    dynamics,
    feed_power_load,
    friction_n,
    paper001_axes,
)
from cnc_plant_sim.models.plant import PLANTS, Plant, make_plant

DT_S = 1.0e-3


def plant(axes: tuple[str, ...] = ("x", "y"), **config: Any) -> MassFrictionPlant:
    built = make_plant({"model": "paper001", "axes": list(axes), **config})
    assert isinstance(built, MassFrictionPlant)
    return built


def hold(p: MassFrictionPlant, commands: list[float], seconds: float, dt_s: float = DT_S) -> np.ndarray:
    """Hold ``commands`` for ``seconds``; the velocities after every step, shape (steps, n)."""
    out = []
    for _ in range(round(seconds / dt_s)):
        p.step(commands, dt_s)
        out.append(p.state()[1])
    return np.array(out)


# ---------------------------------------------------------------- stiction and friction


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize(("axis", "breakaway_n"), [("x", 4.0), ("y", 5.5)])
def test_a_command_below_breakaway_keeps_the_axis_still_and_just_above_moves_it(
        axis: str, breakaway_n: float, sign: float) -> None:
    p = plant((axis,))
    assert p.describe()["breakaway_n"][axis] == pytest.approx(breakaway_n)
    p.reset([0.002])
    hold(p, [sign * (breakaway_n - 1e-6)], 1.0)
    assert p.positions_m()[0] == 0.002 and p.velocities_m_s()[0] == 0.0
    assert p.forces_n()[0] == pytest.approx(sign * (breakaway_n - 1e-6))  # static friction balances the command
    hold(p, [sign * (breakaway_n + 1e-3)], 0.1)
    assert p.velocities_m_s()[0] * sign > 0.0 and (p.positions_m()[0] - 0.002) * sign > 0.0


@pytest.mark.parametrize("axis", ["x", "y"])
def test_the_stribeck_part_decays_from_breakaway_to_coulomb(axis: str) -> None:
    prm = axis_params(paper001_axes((axis,), {})[0])
    speeds = np.array([1e-9, 0.1, 0.5, 1.0, 2.0, 5.0])
    kinetic = np.array([friction_n(v, prm) for v in speeds]) - prm.viscous * speeds
    assert kinetic[0] == pytest.approx(prm.breakaway_n)
    assert_allclose(kinetic, prm.coulomb_n + prm.stribeck_n * np.exp(-prm.stribeck_decay * speeds), rtol=1e-12)
    assert np.all(np.diff(kinetic) < 0.0) and kinetic[-1] == pytest.approx(prm.coulomb_n, abs=1e-3)
    assert friction_n(-0.5, prm) == -friction_n(0.5, prm)


@pytest.mark.parametrize(("axis", "force_n"), [("x", 4.5), ("y", 6.0), ("x", 3.95)])
def test_the_steady_velocity_under_a_constant_force_solves_the_friction_balance(axis: str, force_n: float) -> None:
    viscous = 1.0  # a larger B than Table 1's: m/B = 0.45 s, so the steady state comes within seconds
    p = plant((axis,), axis_overrides={axis: {"viscous": viscous}}, mass_friction={"length_unit": "m"})
    prm = axis_params(p.axis_configs[0])
    hold(p, [prm.breakaway_n + 0.5], 0.5)  # break away; then hold the force (3.95 N lies below X's breakaway)
    hold(p, [force_n], 12.0)
    slowest = math.log(prm.stribeck_decay * prm.stribeck_n / viscous) / prm.stribeck_decay  # the friction's minimum
    expected = brentq(lambda v: friction_n(v, prm) - force_n, slowest, 100.0)
    assert p.velocities_m_s()[0] == pytest.approx(expected, rel=1e-6)
    assert p.forces_n()[0] == pytest.approx(force_n, rel=1e-6)


def test_one_step_follows_scipy_solve_ivp_and_substeps_converge_at_second_order() -> None:
    errors = []
    for substeps in (1, 4):
        p = plant(("x",), substeps=substeps, mass_friction={"length_unit": "m"})  # Stribeck over 0.5 m/s: strongest
        prm = axis_params(p.axis_configs[0])
        times = np.arange(1, 501) * DT_S
        positions = [(p.step([6.0], DT_S), p.positions_m()[0])[1] for _ in times]
        exact = solve_ivp(dynamics, (0.0, times[-1]), [0.0, 0.0], args=(6.0, prm), method="DOP853", rtol=1e-11,
                          atol=1e-14, t_eval=times).y[0]
        errors.append(np.max(np.abs(np.array(positions) - exact)) / abs(exact[-1]))
    assert errors[0] < 1e-5  # measured 2.6e-6
    assert errors[0] / errors[1] > 10.0  # measured 16: second order in the sub-step


def sinusoid(amplitude_n: float, periods: int = 3, period_s: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Y under ``amplitude_n · sin(2πt/period_s)``: velocities [m/s] and friction forces [N] after every step."""
    p = plant(("y",), mass_friction={"length_unit": "m"})
    velocities, forces = [], []
    for k in range(round(periods * period_s / DT_S)):
        p.step([amplitude_n * math.sin(2.0 * math.pi * k * DT_S / period_s)], DT_S)
        velocities.append(p.velocities_m_s()[0])
        forces.append(p.forces_n()[0])
    return np.array(velocities), np.array(forces)


@pytest.mark.parametrize(("amplitude_n", "stops"), [(2.0 * 5.5, 0), (1.2 * 5.5, 6)])
def test_a_slow_sinusoid_reverses_the_axis_once_per_half_period_with_no_chattering(
        amplitude_n: float, stops: int) -> None:
    v, f = sinusoid(amplitude_n)
    moving = v != 0.0
    signs = np.sign(v[moving])
    assert int(np.sum(signs[1:] != signs[:-1])) == 5  # once per half period (six of them) after the first
    # 2×breakaway: the axis reverses within a step, never resting; 1.2×: it rests once after each of the
    # six motion phases (and starts six times): no stick-slip within a half period
    assert int(np.sum(~moving[1:] & moving[:-1])) == stops
    assert int(np.sum(moving[1:] & ~moving[:-1])) == max(stops, 1)
    assert np.all(f[moving] * v[moving] > 0.0)  # the friction always opposes the motion: it only dissipates


# ---------------------------------------------------------------- faults


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, None, "1"])
def test_a_non_finite_command_is_refused_naming_the_axis_and_no_axis_moves(bad: Any) -> None:
    p = plant()
    hold(p, [6.0, 8.0], 0.05)
    before = p.state()
    with pytest.raises(FaultError, match="axis y: command must be finite"):
        p.step([6.0, bad], DT_S)
    assert p.state() == before


def test_a_wrong_count_or_period_is_refused() -> None:
    p = plant()
    with pytest.raises(FaultError, match=r"commands must have 2 entries \['x', 'y'\], got 1"):
        p.step([1.0], DT_S)
    with pytest.raises(FaultError, match="dt_s must be finite and > 0, got 0.0"):
        p.step([1.0, 1.0], 0.0)
    with pytest.raises(FaultError, match="axis x: reset position_m must be finite"):
        p.reset([math.nan, 0.0])


# ---------------------------------------------------------------- config and registry


@pytest.mark.parametrize(("mapping", "message"), [
    ({"axis_overrides": {"x": {"mass": 0.0}}}, "axis_overrides.x.mass must be in [1e-06, 1000000.0], got 0.0"),
    ({"axis_overrides": {"y": {"coulomb_n": -1.0}}},
     "axis_overrides.y.coulomb_n must be in [0.0, 1000000.0], got -1.0"),
    ({"axis_overrides": {"x": {"gain": 1.0}}}, "axis_overrides.x.gain: unknown key; valid keys are ['coulomb_n'"),
    ({"axes": ["x", "w"]}, "axes: paper001 has axes ['x', 'y', 'z'], got 'w'"),
    ({"mass_friction": {"length_unit": "inch"}},
     "mass_friction.length_unit must be one of ['m', 'mm', 'um'], got 'inch'"),
    ({"mass_friction": {"cutting_load": "x"}},
     "mass_friction.cutting_load must be one of ['feed_power', 'none'], got 'x'"),
    ({"mass_friction": {"cutting_exponent": 4.0}}, "mass_friction.cutting_exponent must be in [0.0, 3.0], got 4.0"),
    ({"mass_friction": {"cutting_force": 1.0}}, "mass_friction.cutting_force: unknown key; valid keys are"),
])
def test_a_bad_config_is_refused_naming_the_option_and_its_bound(mapping: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError) as info:
        plant(**{"axes": ["x", "y"], **mapping})
    assert message in str(info.value)


def test_the_registry_builds_table1_from_a_mapping() -> None:
    p = make_plant({"model": "paper001", "axes": ["x", "y", "z"]})
    assert isinstance(p, Plant) and isinstance(p, MassFrictionPlant) and PLANTS["paper001"].build is not None
    assert p.command_unit == "N" and p.axis_names == ("x", "y", "z")
    axes = p.describe()["axes"]
    assert axes["x"] == PAPER001_AXES["x"] and axes["y"] == PAPER001_AXES["y"] and axes["z"] == axes["y"]
    assert p.describe()["length_unit"] == MassFrictionOptions().length_unit == "mm"


def test_describe_round_trips_the_parameters() -> None:
    p = plant(axis_overrides={"x": {"mass": 0.9}}, substeps=3,
              mass_friction={"length_unit": "um", "cutting_load": "feed_power", "cutting_force_n": 7.0})
    d = p.describe()
    again = make_plant({"model": d["model"], "axes": list(d["axes"]), "substeps": d["substeps"],
                        "axis_overrides": d["axes"], "mass_friction": d["options"]})
    assert again.describe() == d and d["axes"]["x"]["mass"] == 0.9 and d["options"]["length_unit"] == "um"


def test_the_interface_is_si_whatever_the_model_length_unit() -> None:
    runs = {}
    for unit in ("m", "mm"):
        p = plant(mass_friction={"length_unit": unit})
        p.reset([0.001, -0.002])
        assert_allclose(p.positions_m(), [0.001, -0.002], rtol=1e-15)
        before = p.positions_m()
        hold(p, [5.0, -7.0], 0.05)
        runs[unit] = (p.positions_m() - before, p.velocities_m_s())
    # the same numbers in model units: the SI motion of the mm reading is 1000 times smaller
    assert_allclose(runs["mm"][0] * 1e3, runs["m"][0], rtol=1e-9)
    assert_allclose(runs["mm"][1] * 1e3, runs["m"][1], rtol=1e-9)


# ---------------------------------------------------------------- cutting load


def test_the_cutting_load_is_off_by_default() -> None:
    p = plant(("x",))
    hold(p, [5.0], 0.05)
    v_model = p.velocities_m_s()[0] / 1e-3
    assert p.forces_n()[0] == pytest.approx(friction_n(v_model, axis_params(p.axis_configs[0])), rel=1e-12)


def test_the_feed_power_load_follows_the_feed_with_its_cross_part() -> None:
    options = MassFrictionOptions(cutting_load="feed_power", cutting_force_n=200.0, cutting_normal_ratio=0.5)
    v_ref = options.cutting_speed_mm_s * 1e-3
    assert_allclose(feed_power_load([v_ref, 0.0], options), [200.0, 100.0])
    # along -y: the cross part lies along n = t turned +90° = +x
    assert_allclose(feed_power_load([0.0, -2.0 * v_ref], options), np.array([100.0, -200.0]) * 2.0 ** 0.75)
    assert feed_power_load([0.0, 0.0], options) == [0.0, 0.0]
    assert_allclose(feed_power_load([v_ref], options), [200.0])  # one axis: no cross part
    assert set(CUTTING_LOADS) == {"none", "feed_power"}


def test_the_cutting_load_acts_on_the_plant_and_is_reported_in_its_forces() -> None:
    loaded = plant(mass_friction={"cutting_load": "feed_power", "cutting_force_n": 3.0, "length_unit": "m"})
    free = plant(mass_friction={"length_unit": "m"})
    for p in (loaded, free):
        hold(p, [8.0, 8.0], 0.2)
    assert np.all(loaded.velocities_m_s() < free.velocities_m_s())
    v = loaded.velocities_m_s()
    prms = [axis_params(c) for c in loaded.axis_configs]
    expected = feed_power_load(v.tolist(), loaded.options)
    friction = [friction_n(x, prm) for x, prm in zip(v, prms)]
    assert_allclose(loaded.forces_n(), np.add(friction, expected), rtol=0.02)  # the load is held from the step's start


# ---------------------------------------------------------------- the plant node


@pytest.mark.nodes
def test_the_plant_node_builds_paper001_with_its_overrides() -> None:
    from cnc_contour_control.testing import InProcessNode
    from cnc_plant_sim.nodes.plant_node import PlantNode

    params = {"model": "paper001", "axes": ["x", "y"], "sample_time_s": 0.001, "duration_s": 1.0,
              "axis_overrides.x.mass": 0.9, "mass_friction.length_unit": "m",
              "mass_friction.cutting_load": "feed_power"}
    with InProcessNode(PlantNode, params) as node:
        built = node.node.plant
        assert isinstance(built, MassFrictionPlant)
        d = built.describe()
        assert d["axes"]["x"]["mass"] == 0.9 and d["axes"]["y"] == PAPER001_AXES["y"]
        assert d["options"]["length_unit"] == "m" and d["options"]["cutting_load"] == "feed_power"
