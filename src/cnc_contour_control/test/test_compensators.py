"""Compensators: the neural network's passes and learning law, CCC, ILC, state files, guards, configs, registry."""
from __future__ import annotations

import math
import re
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.compensators import (
    COMPENSATORS,
    Compensator,
    CompensatorSample,
    IterativeLearningCompensator,
    NeuralCompensator,
    NeuralConfig,
    compensator_config_class,
    make_compensator,
)
from cnc_contour_control.compensators.neural import bipolar_sigmoid
from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import ParamSpec, declared_bounds, flat_specs
from cnc_plant_sim.models.plant import Plant, make_plant

DT_S = 0.001
AXES = ("x", "y")
#: Settings that learn on the test loop below within a few runs (the paper's η = 0.05 on mm does not: module doc).
LEARNING = {"eta": 5e-3, "beta": 10.0, "output_input_scale": 0.01, "position_input_scale_per_m": 100.0}


def sample(tick: int = 0, ref: tuple[float, float] = (0.0, 0.0), pos: tuple[float, float] = (0.0, 0.0),
           contour_m: float = 0.0, angle_rad: float = 0.0) -> CompensatorSample:
    s = CompensatorSample(2, DT_S)
    s.tick, s.ref_position_m, s.position_m = tick, list(ref), list(pos)
    s.contour_error_m, s.angle_rad = contour_m, angle_rad
    s.tracking_error_m = [r - p for r, p in zip(ref, pos)]
    return s


def neural(tmp_path: Path | None = None, seed: int = 3, **params: Any) -> NeuralCompensator:
    """A network with random output weights too (loaded from a file), so every weight has a gradient."""
    comp = NeuralCompensator(build_config(NeuralConfig, {"init_scale": 0.5, "seed": seed, **params}), AXES)
    if tmp_path is not None:
        rng = np.random.default_rng(seed + 1)
        file = tmp_path / "start.npz"
        np.savez(file, input_weights=comp.input_weights, output_weights=rng.uniform(-2, 2, (2, 6)))
        comp.load(file)
    return comp


def reference_output(v: np.ndarray, w: np.ndarray, z: list[float]) -> np.ndarray:
    """The network of Eqs. 5, 6 written plainly: W [f(V [z, 1]), 1] with f = (1 − e^−q)/(1 + e^−q)."""
    q = v @ np.append(z, 1.0)
    o = (1.0 - np.exp(-q)) / (1.0 + np.exp(-q))
    return w @ np.append(o, 1.0)


# --- the network's passes ---------------------------------------------------------------------------------------

def test_bipolar_sigmoid_is_the_papers_formula_and_tanh_of_half_q() -> None:
    q = np.linspace(-30.0, 30.0, 601)
    out = np.empty_like(q)
    bipolar_sigmoid(q, out)
    assert_allclose(out, (1 - np.exp(-q)) / (1 + np.exp(-q)), rtol=1e-12, atol=1e-15)
    assert_allclose(out, np.tanh(q / 2), rtol=1e-15, atol=0)
    extreme = np.array([-1e6, 1e6])
    assert_array_equal(bipolar_sigmoid(extreme, np.empty(2)), [-1.0, 1.0])


def test_forward_pass_takes_the_inputs_of_eq20_in_order(tmp_path: Path) -> None:
    comp = neural(tmp_path, position_input_scale_per_m=100.0, output_input_scale=0.1, output_limit=1e6)
    comp.frozen = True
    v, w = comp.input_weights, comp.output_weights
    first = comp.step(sample(0, ref=(0.011, 0.012), pos=(0.010, 0.013)))
    assert_allclose(first, reference_output(v, w, [1.1, 1.0, 1.0, 1.2, 1.3, 1.3, 0.0, 0.0]), rtol=1e-13)
    second = comp.step(sample(1, ref=(0.021, 0.022), pos=(0.020, 0.023)))
    z = [2.1, 2.0, 1.0, 2.2, 2.3, 1.3, 0.1 * first[0], 0.1 * first[1]]  # c(t−1) and u_N(t−1) of the first tick
    assert_allclose(second, reference_output(v, w, z), rtol=1e-13)


def _loss(comp_config: NeuralConfig, v: np.ndarray, w: np.ndarray, z0: list[float], u0: np.ndarray,
          tick1: CompensatorSample, signs: tuple[float, float]) -> float:
    """E of Section 2.3 for weights (v, w), through a plant whose scaled Jacobian is exactly ``signs``.

    The output of tick 0 moves the tick-1 positions: s·c_k = s·p_k + sign_k (u_k − u0_k); ε_c is the signed
    distance to the line through P − ε n with the left normal n (our sign convention), computed geometrically.
    """
    s, beta = comp_config.error_scale_per_m, comp_config.beta
    u = reference_output(v, w, z0)
    c = np.array(tick1.position_m) + np.array(signs) * (u - u0) / s
    normal = np.array([-math.sin(tick1.angle_rad), math.cos(tick1.angle_rad)])
    on_line = np.array(tick1.position_m) - tick1.contour_error_m * normal
    contour = float((c - on_line) @ normal)
    return 0.5 * float(np.sum((s * (np.array(tick1.ref_position_m) - c)) ** 2)) + 0.5 * beta * (s * contour) ** 2


def test_one_learning_step_is_minus_eta_times_the_finite_difference_gradient_of_e(tmp_path: Path) -> None:
    signs = (1.0, -1.0)
    comp = neural(tmp_path, eta=1e-3, alpha=0.0, beta=2.0, jacobian_signs=list(signs),
                  position_input_scale_per_m=100.0, output_input_scale=0.1, output_limit=1e6)
    v, w = comp.input_weights, comp.output_weights
    tick0 = sample(0, ref=(0.011, 0.012), pos=(0.010, 0.013))
    u0 = np.array(comp.step(tick0))
    z0 = [1.1, 1.0, 1.0, 1.2, 1.3, 1.3, 0.0, 0.0]
    tick1 = sample(1, ref=(0.0212, 0.0223), pos=(0.0205, 0.0231), contour_m=3e-4, angle_rad=0.7)
    comp.step(tick1)
    change = np.concatenate([(comp.input_weights - v).ravel(), (comp.output_weights - w).ravel()])
    theta = np.concatenate([v.ravel(), w.ravel()])
    gradient = np.empty_like(theta)
    for i in range(theta.size):
        values = []
        for h in (1e-6, -1e-6):
            t = theta.copy()
            t[i] += h
            values.append(_loss(comp.config, t[:v.size].reshape(v.shape), t[v.size:].reshape(w.shape), z0, u0,
                                tick1, signs))
        gradient[i] = (values[0] - values[1]) / 2e-6
    assert np.count_nonzero(change) == theta.size - 10  # all but the weights of u_N(t−1) = 0 at the first tick
    assert_allclose(change, -1e-3 * gradient, rtol=1e-5, atol=1e-12)


def test_momentum_adds_alpha_times_the_previous_step(tmp_path: Path) -> None:
    with_momentum, without = neural(tmp_path, alpha=0.4, eta=1e-3), neural(tmp_path, alpha=0.0, eta=1e-3)
    ticks = [sample(k, ref=(0.001 * k + 2e-4, 0.002 * k), pos=(0.001 * k, 0.002 * k + 1e-4), contour_m=5e-5,
                    angle_rad=0.3) for k in range(3)]
    weights: dict[str, list[np.ndarray]] = {"with": [], "without": []}
    for tick in ticks:
        for name, comp in (("with", with_momentum), ("without", without)):
            comp.step(tick)
            weights[name].append(np.concatenate([comp.input_weights.ravel(), comp.output_weights.ravel()]))
    first_step = weights["without"][1] - weights["without"][0]
    assert_array_equal(weights["with"][1], weights["without"][1])  # no previous step at the first update
    second_without = weights["without"][2] - weights["without"][1]
    assert_allclose(weights["with"][2] - weights["with"][1], second_without + 0.4 * first_step, rtol=1e-9, atol=1e-15)


def test_a_positive_contour_error_teaches_a_push_to_the_right_of_travel() -> None:
    comp = neural(None, eta=1e-3, beta=1.0)  # output weights 0: one step moves them alone, by −η g [o, 1]
    travel_x = sample(0, contour_m=1e-4, angle_rad=0.0)  # the left of +x travel is +y
    comp.step(travel_x)
    comp.step(travel_x)  # learns from ε_c = +0.1 mm alone (no tracking error)
    comp.reset()
    comp.frozen = True
    x, y = comp.step(travel_x)
    assert x == 0.0 and y < -1e-6


# --- learning, frozen, guards -----------------------------------------------------------------------------------

def test_frozen_keeps_the_weights_and_still_applies_the_output(tmp_path: Path) -> None:
    comp = neural(tmp_path)
    comp.frozen = True
    v, w = comp.input_weights, comp.output_weights
    outputs = [comp.step(sample(k, ref=(1e-3, 0.0), contour_m=1e-4)) for k in range(5)]
    assert_array_equal(comp.input_weights, v)
    assert_array_equal(comp.output_weights, w)
    assert all(abs(u[0]) > 0.01 for u in outputs)


@pytest.mark.parametrize(("field", "axis"), [("position_m", 1), ("ref_position_m", 0), ("tracking_error_m", 1)])
def test_a_non_finite_sample_is_refused_naming_field_and_axis_before_the_weights_change(
        tmp_path: Path, field: str, axis: int) -> None:
    comp, twin = neural(tmp_path), neural(tmp_path)
    good = [sample(k, ref=(1e-3 * k, 2e-4), pos=(1e-3 * k - 1e-5, 1e-4), contour_m=2e-5) for k in range(3)]
    for c in (comp, twin):
        c.step(good[0])
    v, w = comp.input_weights, comp.output_weights
    bad = sample(1, ref=(1e-3, 2e-4), pos=(1e-3, 1e-4))
    getattr(bad, field)[axis] = math.nan
    with pytest.raises(FaultError, match=rf"neural compensator: {field}\[{AXES[axis]}\] must be finite, got nan"):
        comp.step(bad)
    assert_array_equal(comp.input_weights, v)
    assert_array_equal(comp.output_weights, w)
    assert comp.step(good[1]) == twin.step(good[1])  # nothing of the bad sample was kept


@pytest.mark.parametrize("field", ["contour_error_m", "angle_rad", "dt_s"])
def test_a_non_finite_scalar_is_refused_by_every_compensator(field: str) -> None:
    for name in COMPENSATORS:
        comp = make_compensator(name, {}, AXES, DT_S)
        bad = sample(0)
        setattr(bad, field, math.inf)
        with pytest.raises(FaultError, match=rf"{field} must be finite, got inf"):
            comp.step(bad)


def test_a_sample_of_the_wrong_length_is_refused() -> None:
    bad = sample(0)
    bad.position_m = [0.0]
    with pytest.raises(FaultError, match=r"position_m must have 2 values \(axes \['x', 'y'\]\), got 1"):
        make_compensator("ccc", {}, AXES, DT_S).step(bad)


def test_the_divergence_guard_stops_learning_and_zeroes_the_output(tmp_path: Path) -> None:
    comp = neural(tmp_path, eta=1e3, weight_norm_limit=100.0)
    comp.step(sample(0))
    v, w = comp.input_weights, comp.output_weights
    out = comp.step(sample(1, ref=(0.01, -0.01), contour_m=1e-3))
    assert out == [0.0, 0.0]
    assert comp.fault is not None and "weight_norm_limit 100.0" in comp.fault
    assert_array_equal(comp.input_weights, v)  # the last good weights are kept
    assert_array_equal(comp.output_weights, w)
    comp.reset()
    assert comp.step(sample(0, ref=(0.01, 0.0))) == [0.0, 0.0] and comp.fault is not None


def test_an_output_pinned_at_the_limit_trips_the_guard(tmp_path: Path) -> None:
    comp = neural(tmp_path, output_limit=1e-3, pinned_ticks=3)
    comp.frozen = True
    outputs = [comp.step(sample(k)) for k in range(4)]
    assert all(abs(u) == 1e-3 for u in outputs[0] + outputs[1])
    assert outputs[2] == outputs[3] == [0.0, 0.0]
    assert comp.fault is not None and "pinned at output_limit 0.001 for 3 ticks" in comp.fault


# --- closed loop: paper 000's drives with a slower, weaker Y axis, a circle -------------------------------------

RADIUS_M, FEED_M_S = 0.005, 1.0 / 60.0


def _loop() -> tuple[Plant, list[ServoController]]:
    plant = make_plant({"model": "paper000", "variation": {"gain_pct": 0, "time_constant_pct": 0, "friction_pct": 0},
                        "axis_overrides": {"y": {"gain_blu_s_per_dac": 20.0, "time_constant_s": 0.09}}})
    servos = [ServoController(ServoConfig.from_mapping({"axis_name": a, "quantum": 0.0})) for a in AXES]
    return plant, servos


def circle_run(comp: Compensator, plant: Plant, servos: list[ServoController]) -> float:
    """One CCW circle from the origin with the exact contour error; returns its RMS [m]."""
    omega = FEED_M_S / RADIUS_M
    plant.reset([0.0, 0.0])
    for servo in servos:
        servo.reset()
    comp.reset()
    s, squares = CompensatorSample(2, DT_S), 0.0
    ticks = int(2 * math.pi / omega / DT_S)
    for k in range(ticks):
        phi = omega * k * DT_S - math.pi / 2
        ref = [RADIUS_M * math.cos(phi), RADIUS_M * (1 + math.sin(phi))]
        ref_v = [-FEED_M_S * math.sin(phi), FEED_M_S * math.cos(phi)]
        pos, vel = plant.state()
        dx, dy = pos[0], pos[1] - RADIUS_M
        s.tick, s.ref_position_m, s.position_m = k, ref, pos
        s.contour_error_m = RADIUS_M - math.hypot(dx, dy)  # inside the CCW circle is left of travel
        s.angle_rad = math.atan2(dy, dx) + math.pi / 2
        s.tracking_error_m = [ref[0] - pos[0], ref[1] - pos[1]]
        correction = comp.step(s)
        plant.step([servo.parts(DT_S, ref[i], ref_v[i], 0.0, pos[i], vel[i], correction[i])[0]
                    for i, servo in enumerate(servos)], DT_S)
        squares += s.contour_error_m ** 2
    comp.end_run()
    return math.sqrt(squares / ticks)


@pytest.fixture(scope="module")
def pid_only_rms() -> float:
    return circle_run(make_compensator("none", {}, AXES, DT_S), *_loop())


def test_ccc_reduces_the_contour_error_within_one_run(pid_only_rms: float) -> None:
    rms = circle_run(make_compensator("ccc", {}, AXES, DT_S), *_loop())
    assert rms < 0.6 * pid_only_rms


@pytest.mark.parametrize(("name", "params", "runs", "ratio"), [
    ("ilc", {"advance_samples": 20}, 6, 0.5),
    ("neural", LEARNING, 6, 0.6),
])
def test_learning_reduces_the_contour_error_over_runs(pid_only_rms: float, name: str, params: dict[str, Any],
                                                      runs: int, ratio: float) -> None:
    comp, loop = make_compensator(name, params, AXES, DT_S), _loop()
    curve = [circle_run(comp, *loop) for _ in range(runs)]
    assert curve[-1] < ratio * min(curve[0], pid_only_rms)  # better than the first run's and the PID's alone
    assert all(later < 1.05 * earlier for earlier, later in zip(curve, curve[1:]))  # run after run
    assert comp.fault is None


def test_ccc_pushes_a_positive_contour_error_to_the_right() -> None:
    comp = make_compensator("ccc", {"ki": 0.0}, AXES, DT_S)
    x, y = comp.step(sample(0, contour_m=1e-4, angle_rad=0.0))
    assert x == pytest.approx(0.0, abs=1e-12) and y == pytest.approx(-20.0)  # −kp·ε along +y, the left normal


# --- ILC specifics ----------------------------------------------------------------------------------------------

def ilc(**params: Any) -> IterativeLearningCompensator:
    comp = make_compensator("ilc", params, AXES, DT_S)
    assert isinstance(comp, IterativeLearningCompensator)
    return comp


def test_ilc_update_is_zero_phase_and_handles_another_run_length() -> None:
    comp = ilc(learning_gain=2.0, advance_samples=3, cutoff_hz=50.0)
    t = np.arange(2000) * DT_S
    errors = np.sin(2 * math.pi * 2.0 * t)  # 2 Hz: passes the 50 Hz Q without delay
    updated = comp.update(np.zeros(1500), errors)
    assert updated.shape == (2000,)
    advanced = 2.0 * np.sin(2 * math.pi * 2.0 * (t + 3 * DT_S))
    assert_allclose(updated[100:1900], advanced[100:1900], atol=2e-3)
    shorter = comp.update(np.ones(3000), np.zeros(1000))
    assert_allclose(shorter, np.ones(1000), atol=1e-9)
    fast = comp.update(np.zeros(2000), np.sin(2 * math.pi * 400.0 * t))
    assert np.abs(fast[100:1900]).max() < 0.05  # above the cut-off: not learned


def test_ilc_plays_the_feedforward_along_minus_the_normal_and_zero_past_its_end() -> None:
    comp = ilc(learning_gain=1e5, advance_samples=0, cutoff_hz=400.0)
    for k in range(50):
        comp.step(sample(k, contour_m=1e-4, angle_rad=0.0))
    comp.end_run()
    assert_allclose(comp.feedforward, 10.0, rtol=1e-6)
    comp.reset()
    x, y = comp.step(sample(0, angle_rad=0.0))
    assert x == pytest.approx(0.0, abs=1e-9) and y == pytest.approx(-10.0, rel=1e-6)
    assert comp.step(sample(60, angle_rad=0.0)) == [0.0, 0.0]


def test_ilc_frozen_learns_nothing_and_a_non_finite_update_faults() -> None:
    comp = ilc()
    comp.frozen = True
    comp.step(sample(0, contour_m=1e-4))
    comp.end_run()
    assert comp.feedforward.size == 0
    comp.frozen = False
    huge = ilc(learning_gain=1e12, advance_samples=0)
    huge.step(sample(0, contour_m=1e300))
    huge.end_run()
    assert huge.fault is not None and "non-finite" in huge.fault and huge.feedforward.size == 0


# --- state files ------------------------------------------------------------------------------------------------

def test_neural_save_load_round_trip_is_exact(tmp_path: Path) -> None:
    comp = neural(tmp_path)
    for k in range(5):
        comp.step(sample(k, ref=(1e-4 * k, 0.0), contour_m=1e-5))
    comp.save(tmp_path / "weights")
    other = neural(None, seed=99)
    other.load(tmp_path / "weights")
    assert_array_equal(other.input_weights, comp.input_weights)
    assert_array_equal(other.output_weights, comp.output_weights)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["start.npz", "weights"]  # no suffix added, no temp left


def test_ilc_save_load_round_trip_is_exact_and_checks_the_sample_time(tmp_path: Path) -> None:
    comp = ilc()
    for k in range(100):
        comp.step(sample(k, contour_m=1e-5 * math.sin(0.1 * k)))
    comp.end_run()
    comp.save(tmp_path / "ff.npz")
    other = ilc()
    other.load(tmp_path / "ff.npz")
    assert_array_equal(other.feedforward, comp.feedforward)
    with pytest.raises(ConfigError, match=r"ff.npz' was learned at sample_time_s 0.001, this compensator runs at 0.002"
                       ):
        make_compensator("ilc", {}, AXES, 0.002).load(tmp_path / "ff.npz")


def _bad_files(tmp_path: Path) -> list[tuple[Path, str]]:
    good = {"input_weights": np.zeros((5, 9)), "output_weights": np.zeros((2, 6))}
    cases: list[tuple[str, Any, str]] = [
        ("missing.npz", None, "does not exist"),
        ("text.npz", b"input_weights = 1\n", r"is not a numeric \.npz archive"),
        ("array.npy", np.zeros(3), r"is a single \.npy array, not an \.npz archive"),
        ("objects.npz", {**good, "output_weights": np.array([None, 1], dtype=object)}, "object array"),
        ("strings.npz", {**good, "output_weights": np.array(["a", "b"])}, r"'output_weights' must hold numbers"),
        ("shape.npz", {**good, "input_weights": np.zeros((5, 8))}, r"'input_weights' has shape \(5, 8\), "
                                                                   r"expected \(5, 9\)"),
        ("nan.npz", {**good, "output_weights": np.where(np.eye(2, 6) > 0, np.nan, 0.0)},
         r"'output_weights' holds 2 non-finite entries \(the first at index \(0, 0\)\)"),
        ("missing_key.npz", {"input_weights": good["input_weights"]}, r"lacks 'output_weights'"),
        ("extra_key.npz", {**good, "momentum": np.zeros(3)}, r"holds \['momentum'\] that a neural compensator"),
        ("huge.npz", {**good, "output_weights": np.full((2, 6), 1e7)}, r"norm .* above weight_norm_limit"),
    ]
    files = []
    for name, content, problem in cases:
        path = tmp_path / name
        if isinstance(content, bytes):
            path.write_bytes(content)
        elif isinstance(content, np.ndarray):
            np.save(path, content)
        elif content is not None:
            np.savez(path, **content)
        files.append((path, problem))
    truncated = tmp_path / "truncated.npz"
    np.savez(truncated, **good)
    truncated.write_bytes(truncated.read_bytes()[:200])
    files.append((truncated, r"is not a numeric \.npz archive"))
    return files


def test_every_bad_weights_file_is_refused_naming_the_file_and_the_problem(tmp_path: Path) -> None:
    comp = neural(tmp_path)
    v = comp.input_weights
    for path, problem in _bad_files(tmp_path):
        with pytest.raises(ConfigError, match=problem) as caught:
            comp.load(path)
        assert str(path) in str(caught.value)
        assert_array_equal(comp.input_weights, v)


def test_a_state_file_of_another_compensator_is_refused(tmp_path: Path) -> None:
    neural(None).save(tmp_path / "w.npz")
    assert zipfile.is_zipfile(tmp_path / "w.npz")
    with pytest.raises(ConfigError, match=r"ilc compensator feedforward .*w.npz' lacks 'feedforward'"):
        ilc().load(tmp_path / "w.npz")
    with pytest.raises(ConfigError, match=r"holds \['input_weights', 'output_weights'\] that a ccc"):
        make_compensator("ccc", {}, AXES, DT_S).load(tmp_path / "w.npz")


# --- configs and the registry -----------------------------------------------------------------------------------

def _bounds() -> list[Any]:
    return [pytest.param(entry.config_class, spec, bound, direction,
                         id=f"{name}.{spec.name}{'<' if direction < 0 else '>'}")
            for name, entry in COMPENSATORS.items() for spec, bound, direction in declared_bounds(entry.config_class)]


@pytest.mark.parametrize(("cls", "spec", "bound", "direction"), _bounds())
def test_a_bound_is_accepted_and_the_next_value_beyond_refused_naming_it(
        cls: type, spec: ParamSpec, bound: float, direction: float) -> None:
    value = int(bound) if spec.kind is int else float(bound)
    assert getattr(build_config(cls, {spec.name: value}), spec.name) == value
    outside = bound + direction if spec.kind is int else math.nextafter(bound, direction * math.inf)
    with pytest.raises(ConfigError, match=re.escape(f"{spec.name} must be in [{spec.info.low}, {spec.info.high}]")):
        build_config(cls, {spec.name: int(outside) if spec.kind is int else outside})


def test_every_field_is_declared_with_a_description() -> None:
    for entry in COMPENSATORS.values():
        assert all(spec.info.description for spec in flat_specs(entry.config_class))


@pytest.mark.parametrize(("name", "params", "message"), [
    ("neural", {"eta": -1.0}, r"neural.eta must be in \[0.0, 1000.0\], got -1.0"),
    ("neural", {"hidden_units": 2.5}, r"neural.hidden_units must be an integer, got 2.5"),
    ("neural", {"jacobian_signs": [1.0, 0.5]}, r"neural.jacobian_signs\[1\] must be \+1 or -1, got 0.5"),
    ("neural", {"jacobian_signs": [1.0]}, r"neural.jacobian_signs must have one value per axis \['x', 'y'\]"),
    ("neural", {"etta": 0.1}, r"neural.etta: unknown key; valid keys are \['alpha', 'beta'"),
    ("ccc", {"axis_gains": [1.0, "a"]}, r"ccc.axis_gains\[1\] must be a number"),
    ("ilc", {"cutoff_hz": 600.0}, r"ilc.cutoff_hz must be < the Nyquist frequency 500 Hz"),
    ("ilc", {}, r"ilc.sample_time_s must be > 0, got 0"),
    ("pid", {}, r"compensator must be one of \['ccc', 'ilc', 'neural', 'none'\], got 'pid'"),
])
def test_bad_settings_are_refused_naming_option_bound_and_value(name: str, params: dict[str, Any],
                                                                message: str) -> None:
    period = 0.0 if message.startswith("ilc.sample_time_s") else DT_S
    with pytest.raises(ConfigError, match=message):
        make_compensator(name, params, AXES, period)


@pytest.mark.parametrize("name", sorted(COMPENSATORS))
def test_every_registered_compensator_keeps_the_protocol(name: str, tmp_path: Path) -> None:
    comp = make_compensator(name, {}, ("x", "y", "z"), DT_S)
    assert isinstance(comp, Compensator) and comp.axis_names == ("x", "y", "z")
    assert isinstance(build_config(compensator_config_class(name), {}), compensator_config_class(name))
    s = CompensatorSample(3, DT_S)
    s.contour_error_m = 1e-5
    out = comp.step(s)
    assert len(out) == 3 and out[2] == 0.0 and comp.fault is None
    comp.end_run()
    comp.save(tmp_path / "state.npz")
    comp.load(tmp_path / "state.npz")
    comp.reset()
