"""Contour-error estimators: signs, agreement with the exact contour distance, 3 axes, memory, step cost, bad input."""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import declared_bounds
from cnc_contour_control.estimators import (
    ESTIMATORS,
    ContourEstimate,
    PathEstimator,
    PathEstimatorConfig,
    WindowEstimator,
    WindowEstimatorConfig,
    estimator_config_class,
    make_estimator,
    signed_contour_error,
    signed_segment_error,
)
from cnc_contour_control.estimators.window import line_error, line_error_2
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment, Program
from cnc_contour_control.motion.interpolation import Interpolator

T_S = 1e-3
FEED_M_S = 0.05


# ----------------------------------------------------------------------------------- helpers
def _circle(clockwise: bool, radius_m: float = 0.01, rise_m: float = 0.0, turns: int = 1) -> Program:
    n = 3 if rise_m else 2
    start, center = np.zeros(n), np.zeros(n)
    center[1] = radius_m
    segments = []
    for turn in range(turns):
        start_turn = start.copy()
        start_turn[n - 1] += turn * rise_m if rise_m else 0.0
        end = start_turn.copy()
        if rise_m:
            end[2] += rise_m
        segments.append(ArcSegment(start_turn, end, center, clockwise, (0, 1), FEED_M_S))
    names = ("x", "y", "z")[:n]
    return Program("circle", names, tuple(segments))


def _waves(count: int, radius_m: float = 0.005) -> Program:
    """``count`` semicircles of alternating direction along x: tangent-continuous, many segments."""
    segments = []
    for k in range(count):
        start, end = np.array([2 * k * radius_m, 0.0]), np.array([2 * (k + 1) * radius_m, 0.0])
        center = np.array([(2 * k + 1) * radius_m, 0.0])
        segments.append(ArcSegment(start, end, center, k % 2 == 0, (0, 1), FEED_M_S))
    return Program("waves", ("x", "y"), tuple(segments))


def _along(program: Program, s_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and unit tangents at global arc lengths ``s_m`` (M,): (M, n) each."""
    s = np.clip(s_m, 0.0, program.total_length_m)
    index = np.clip(np.searchsorted(program.segment_start_m, s, side="right") - 1, 0, len(program.segments) - 1)
    points, tangents = np.zeros((s.size, program.n_axes)), np.zeros((s.size, program.n_axes))
    for i in np.unique(index):
        rows = index == i
        local = s[rows] - program.segment_start_m[i]
        points[rows], tangents[rows] = program.segments[i].point(local), program.segments[i].tangent(local)
    return points, tangents


def _run(program: Program, lag_s: float = 0.02, offset_m: float = 20e-6,
         duration_s: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """References at 1 kHz from the interpolator; positions ``lag_s`` behind, offset along the in-plane left normal.

    Returns references (M, n), positions (M, n) and the exact signed offsets (M,).
    """
    axes = program.n_axes
    interpolator = Interpolator(program, AxisLimits((0.2,) * axes, (5.0,) * axes))
    end_s = interpolator.duration_s if duration_s is None else duration_s
    times = np.arange(0.0, end_s + T_S / 2, T_S)
    ref = interpolator.sample_array(times)
    lagged = interpolator.sample_array(times - lag_s).path_length_m
    points, tangents = _along(program, lagged)
    normal = np.zeros_like(tangents)
    normal[:, 0], normal[:, 1] = -tangents[:, 1], tangents[:, 0]
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    offset = offset_m * np.sin(2 * math.pi * 3.0 * times)
    return ref.position_m, points + offset[:, None] * normal, offset


def _feed(estimator: Any, refs: np.ndarray, positions: np.ndarray) -> list[ContourEstimate]:
    return [estimator.step(r, p) for r, p in zip(refs.tolist(), positions.tolist())]


def _window(program: Program, **params: Any) -> WindowEstimator:
    return make_estimator("window", params, program)  # type: ignore[return-value]  # the registry returns the base type


def _path(program: Program, **params: Any) -> PathEstimator:
    return make_estimator("path", params, program)  # type: ignore[return-value]  # the registry returns the base type


LINE = Program("line", ("x", "y"), (LineSegment([0.0, 0.0], [0.05, 0.0], FEED_M_S),))


# ----------------------------------------------------------------------------------- signs
@pytest.mark.parametrize("heading_deg", [0.0, 30.0, 90.0, 135.0, 180.0, 250.0, 315.0])
@pytest.mark.parametrize("side", [1.0, -1.0])
@pytest.mark.parametrize("name", sorted(ESTIMATORS))
def test_sign_on_a_line_is_positive_left_of_travel(heading_deg: float, side: float, name: str) -> None:
    heading = math.radians(heading_deg)
    direction = np.array([math.cos(heading), math.sin(heading)])
    left = np.array([-direction[1], direction[0]])
    program = Program("line", ("x", "y"), (LineSegment([0.0, 0.0], 0.02 * direction, FEED_M_S),))
    estimator = make_estimator(name, {}, program)
    for k in range(60):
        ref = (k * 1e-4) * direction
        estimate = estimator.step(ref, ref - 3e-3 * direction + side * 7e-6 * left)
    assert estimate.contour_error_m == pytest.approx(side * 7e-6, abs=1e-12)
    assert estimate.angle_rad == pytest.approx(math.atan2(direction[1], direction[0]), abs=1e-9)
    assert_allclose(estimate.tracking_error_m, 3e-3 * direction - side * 7e-6 * left, atol=1e-15)


@pytest.mark.parametrize("clockwise", [False, True])
@pytest.mark.parametrize("outside", [False, True])
@pytest.mark.parametrize("name", sorted(ESTIMATORS))
def test_sign_on_arcs_left_of_travel_both_directions(clockwise: bool, outside: bool, name: str) -> None:
    program = _circle(clockwise)
    refs, _, _ = _run(program, offset_m=0.0, duration_s=0.3)
    center = program.segments[0].center_m
    lagged = refs[:-30]
    radial = (lagged - center) / np.linalg.norm(lagged - center, axis=1, keepdims=True)
    positions = lagged + (5e-6 if outside else -5e-6) * radial
    estimates = _feed(make_estimator(name, {}, program), refs[30:], positions)
    # centre on the left of a CCW arc: inside is left (> 0); on a CW arc inside is right (< 0)
    expected = (-5e-6 if outside else 5e-6) * (-1.0 if clockwise else 1.0)
    errors = np.array([e.contour_error_m for e in estimates[50:]])
    assert_allclose(errors, expected, atol=0.2e-6)


def test_eq2_with_atan2_is_the_left_normal_component() -> None:
    """Eq. 2 without sign(x2 - x1) and with atan2 of the travel direction: -e'x sin θ + e'y cos θ."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        earlier, step, offset = rng.normal(size=2), rng.normal(size=2), rng.normal(size=2)
        later = earlier + step
        theta = math.atan2(step[1], step[0])
        eq2 = -offset[0] * math.sin(theta) + offset[1] * math.cos(theta)
        error, angle = line_error_2(tuple(later + offset), tuple(later), tuple(earlier), tuple(later), (0, 1))
        assert error == pytest.approx(eq2, abs=1e-12)
        assert angle == pytest.approx(theta)


def test_two_axis_line_error_equals_the_general_one_in_3_axes() -> None:
    rng = np.random.default_rng(4)
    for _ in range(50):
        pos, near, earlier, later = (rng.normal(size=2) for _ in range(4))
        flat = [tuple(np.append(v, 0.0)) for v in (pos, near, earlier, later)]
        two = line_error_2(tuple(pos), tuple(near), tuple(earlier), tuple(later), (0, 1))
        assert_allclose(line_error(*flat, (0, 1)), two, rtol=1e-12, atol=1e-15)


# ----------------------------------------------------------------------------------- agreement
@pytest.mark.parametrize("clockwise", [False, True])
def test_window_path_and_contour_distance_agree_on_a_circle(clockwise: bool) -> None:
    program = _circle(clockwise)
    refs, positions, offset = _run(program)
    window = np.array([e.contour_error_m for e in _feed(_window(program), refs, positions)])
    path = np.array([e.contour_error_m for e in _feed(_path(program), refs, positions)])
    exact, _, _ = signed_contour_error(program, positions)
    distance, _ = program.contour_distance(positions)
    assert_allclose(np.abs(exact), distance, rtol=0, atol=0)
    assert_allclose(exact, offset, atol=1e-12)
    assert_allclose(path, exact, atol=1e-12)
    chord_m = FEED_M_S * T_S
    sagitta_m = chord_m ** 2 / (8 * 0.01)
    assert np.max(np.abs(window - exact)) <= 1.5 * sagitta_m


def test_window_and_path_agree_on_many_tangent_segments() -> None:
    program = _waves(8)
    refs, positions, offset = _run(program)
    window = np.array([e.contour_error_m for e in _feed(_window(program), refs, positions)])
    path_estimates = _feed(_path(program), refs, positions)
    exact, index, _ = signed_contour_error(program, positions)
    assert_allclose(exact, offset, atol=1e-12)
    assert_allclose([e.contour_error_m for e in path_estimates], exact, atol=1e-12)
    assert [e.segment_index for e in path_estimates] == index.tolist()
    assert np.max(np.abs(window - exact)) <= 1.5 * (FEED_M_S * T_S) ** 2 / (8 * 0.005)


def test_window_finds_the_nearest_stored_point_as_a_full_search_would() -> None:
    program = _circle(False)
    refs, positions, _ = _run(program, duration_s=0.6)
    estimator = _window(program)
    for k, (ref, pos) in enumerate(zip(refs.tolist(), positions.tolist())):
        estimate = estimator.step(ref, pos)
        stored = refs[:k + 1][np.r_[True, np.linalg.norm(np.diff(refs[:k + 1], axis=0), axis=1) >= 1e-9]]
        distances = np.linalg.norm(stored - pos, axis=1)
        assert estimate.segment_index == int(np.argmin(distances))
        assert_allclose(estimate.point_b_m, stored[estimate.segment_index])
        if stored.shape[0] > 1:
            neighbours = [i for i in (estimate.segment_index - 1, estimate.segment_index + 1) if 0 <= i < len(stored)]
            other = int(np.argmin(np.linalg.norm(stored[neighbours] - estimate.point_a_m, axis=1)))
            assert_allclose(estimate.point_a_m, stored[neighbours[other]], rtol=0, atol=0)
            assert distances[neighbours[other]] <= min(distances[neighbours]) + 1e-15  # ties go either way


def test_path_estimator_one_point_evaluation_equals_the_array_function() -> None:
    rng = np.random.default_rng(5)
    helix = _circle(False, rise_m=0.002).segments[0]
    line3 = LineSegment([0.0, 0.0, 0.0], [0.01, 0.02, 0.003], FEED_M_S)
    for segment in (_circle(True).segments[0], _waves(2).segments[1], helix, line3):
        program = Program("one", ("x", "y", "z")[:segment.n_axes], (segment,))
        estimator = _path(program)
        points = segment.point(rng.uniform(0, segment.length_m, 40)) + rng.normal(scale=1e-4, size=(40, segment.n_axes))
        error, _, nearest, angle = signed_segment_error(segment, points)
        for k, point in enumerate(points.tolist()):
            estimate = estimator.step(point, point)
            assert estimate.contour_error_m == pytest.approx(error[k], abs=1e-15)
            assert estimate.angle_rad == pytest.approx(angle[k], abs=1e-12)
            assert_allclose(estimate.point_a_m, nearest[k], atol=1e-15)


# ----------------------------------------------------------------------------------- 3 axes
@pytest.mark.parametrize("clockwise", [False, True])
def test_helix_in_3_axes_distance_in_space_sign_in_the_plane(clockwise: bool) -> None:
    program = _circle(clockwise, rise_m=0.003, turns=2)
    refs, positions, offset = _run(program, duration_s=1.2)
    window = np.array([e.contour_error_m for e in _feed(_window(program), refs, positions)])
    path = np.array([e.contour_error_m for e in _feed(_path(program), refs, positions)])
    exact, _, _ = signed_contour_error(program, positions)
    distance, _ = program.contour_distance(positions)
    assert_allclose(np.abs(exact), distance, atol=0)
    assert_allclose(exact, offset, atol=1e-9)  # the in-plane radial offset is normal to the helix
    assert_allclose(np.abs(path), np.abs(exact), atol=1e-12)
    assert_allclose(path, exact, atol=1e-9)  # on the helix (|ε| ~ 1e-10 m, the solver's noise) the sign may differ
    assert np.max(np.abs(window - exact)) < 0.05e-6


def test_3_axis_offset_out_of_the_plane_counts_in_the_distance_not_the_sign() -> None:
    program = Program("line3", ("x", "y", "z"), (LineSegment([0.0, 0.0, 0.0], [0.05, 0.0, 0.0], FEED_M_S),))
    for name in sorted(ESTIMATORS):
        estimator = make_estimator(name, {}, program)
        for k in range(20):
            estimate = estimator.step((k * 1e-4, 0.0, 0.0), (k * 1e-4 - 5e-4, -3e-6, 4e-6))
        assert estimate.contour_error_m == pytest.approx(-5e-6, abs=1e-12), name


# ----------------------------------------------------------------------------------- memory and cost
def test_memory_is_a_bounded_ring() -> None:
    estimator = _window(LINE, memory_points=100)
    for k in range(1000):
        estimate = estimator.step((k * 1e-5, 0.0), (k * 1e-5 - 2e-4, 1e-6))
    assert estimator.stored_count == 1000 and estimator.memory_size == 100
    assert len(estimator._memory) == 100
    assert estimate.segment_index == 979 and estimate.contour_error_m == pytest.approx(1e-6, abs=1e-12)


def test_a_reference_standing_still_is_stored_once_and_the_first_tick_reports_zero() -> None:
    estimator = _window(LINE)
    first = estimator.step((0.0, 0.0), (0.0, 0.0))
    assert (first.contour_error_m, first.angle_rad, first.window_size, first.steps) == (0.0, 0.0, 1, 0)
    for _ in range(10):
        still = estimator.step((0.0, 0.0), (0.0, 2e-6))
    assert estimator.stored_count == 1 and still.contour_error_m == 0.0 and still.window_size == 1
    moved = estimator.step((1e-5, 0.0), (0.0, 2e-6))
    assert estimator.stored_count == 2 and moved.contour_error_m == pytest.approx(2e-6)


def test_window_step_count_is_flat_over_a_60_s_program_at_1_khz() -> None:
    program = _waves(200)
    refs, positions, _ = _run(program, duration_s=60.0)
    estimates = _feed(_window(program), refs, positions)
    steps = np.array([e.steps for e in estimates])
    window = np.array([e.window_size for e in estimates])
    steady = slice(1000, len(estimates) - 1000)
    assert len(estimates) >= 60_000 and np.max(steps[steady]) <= 5
    first, last = slice(1000, 11_000), slice(len(estimates) - 11_000, len(estimates) - 1000)
    assert abs(steps[first].mean() - steps[last].mean()) <= 0.02
    assert abs(window[first].mean() - window[last].mean()) <= 0.05
    assert np.max(window[steady]) <= 8


def test_path_evaluations_per_step_do_not_grow_with_the_program() -> None:
    program = _waves(200)
    refs, positions, _ = _run(program, duration_s=60.0)
    every = 20  # the tracked segment still moves at most one segment per sample
    estimates = _feed(_path(program), refs[::every], positions[::every])
    evaluated = np.array([e.window_size for e in estimates])
    assert estimates[-1].segment_index > 150
    assert np.max(evaluated) <= 3 and np.max([e.steps for e in estimates]) <= 1
    third = len(estimates) // 3
    assert abs(evaluated[:third].mean() - evaluated[-third:].mean()) <= 0.1


# ----------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("name", sorted(ESTIMATORS))
@pytest.mark.parametrize(("which", "axis", "value"), [("position_m", 1, math.nan), ("ref_position_m", 0, math.inf),
                                                      ("position_m", 0, -math.inf)])
def test_non_finite_input_names_input_and_axis_and_leaves_the_state(name: str, which: str, axis: int,
                                                                     value: float) -> None:
    estimator, clean = make_estimator(name, {}, LINE), make_estimator(name, {}, LINE)
    samples = [((k * 1e-4, 0.0), (k * 1e-4 - 5e-4, 2e-6)) for k in range(30)]
    for ref, pos in samples[:20]:
        estimator.step(ref, pos)
        clean.step(ref, pos)
    bad = {"ref_position_m": list(samples[20][0]), "position_m": list(samples[20][1])}
    bad[which][axis] = value
    with pytest.raises(FaultError, match=rf"{which}\[{axis}\] \({'xy'[axis]}\) must be finite"):
        estimator.step(bad["ref_position_m"], bad["position_m"])
    for ref, pos in samples[20:]:
        a, b = estimator.step(ref, pos), clean.step(ref, pos)
        assert (a.contour_error_m, a.segment_index, a.window_size) == (b.contour_error_m, b.segment_index,
                                                                         b.window_size)


def test_wrong_sample_length_is_a_fault() -> None:
    with pytest.raises(FaultError, match="2 entries"):
        _window(LINE).step((0.0, 0.0, 0.0), (0.0, 0.0))


def test_path_estimator_refuses_an_empty_or_single_point_program() -> None:
    class Empty:
        segments: tuple[()] = ()
        n_axes = 2
    with pytest.raises(ConfigError, match="empty"):
        PathEstimator(PathEstimatorConfig(), Empty())  # type: ignore[arg-type]  # a bare stand-in program on purpose
    point = Program("dot", ("x", "y"), (LineSegment([0.0, 0.0], [1e-9, 0.0], FEED_M_S),))
    with pytest.raises(ConfigError, match="single point"):
        make_estimator("path", {}, point)


def _outside(kind: type, bound: float, direction: float) -> Any:
    return int(bound + direction) if kind is int else math.nextafter(bound, direction * math.inf)


@pytest.mark.parametrize(("cls", "spec", "bound", "direction"), [
    pytest.param(cls, spec, bound, direction, id=f"{cls.__name__}.{spec.name}{'<' if direction < 0 else '>'}")
    for cls in (WindowEstimatorConfig, PathEstimatorConfig) for spec, bound, direction in declared_bounds(cls)])
def test_a_config_bound_is_accepted_and_the_value_beyond_refused_naming_it(cls: type, spec: Any, bound: float,
                                                                             direction: float) -> None:
    value = int(bound) if spec.kind is int else float(bound)
    assert getattr(build_config(cls, {spec.name: value}), spec.name) == value
    beyond = _outside(spec.kind, bound, direction)
    with pytest.raises(ConfigError, match=rf"{spec.name} must be in \[.*\], got {beyond!r}"):
        build_config(cls, {spec.name: beyond})


@pytest.mark.parametrize(("params", "message"), [
    ({"memory_points": 10.5}, "memory_points must be an integer"),
    ({"plane": (0, 0)}, "plane must be two distinct axis indices"),
    ({"plane": (0, 2)}, r"plane must be two distinct axis indices in \[0, 1\]"),
    ({"plane": "xy"}, "plane must be two axis indices"),
    ({"memory": 3}, r"unknown key; valid keys are \['max_steps', 'memory_points', 'min_spacing_m', 'plane'\]"),
])
def test_bad_window_params_are_refused_naming_them(params: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        make_estimator("window", params, LINE)


def test_unknown_estimator_lists_the_valid_ones() -> None:
    with pytest.raises(ConfigError, match=r"estimator must be one of \['path', 'window'\]"):
        make_estimator("kalman", {}, LINE)
    assert estimator_config_class("window") is WindowEstimatorConfig


def test_window_axis_count_must_hold_the_plane() -> None:
    with pytest.raises(ConfigError, match="axis_count must be an integer >= 2"):
        WindowEstimator(WindowEstimatorConfig(), 1)
    with pytest.raises(ConfigError, match=r"in \[0, 1\]"):
        WindowEstimator(WindowEstimatorConfig(plane=(0, 2)), 2)
