"""Circular-test analysis (ISO 230-4 quantities) on synthetic circles with known defects."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.geometry import ArcSegment, Program
from cnc_tools.analysis.circular import Circle, analyse_circle, circle_of, fit_circle, reversal_indices
from cnc_tools.analysis.scoring import score_run

R_M = 0.02
AXES = ("x", "y")


def _circle() -> Circle:
    return Circle((0.0, 0.0), R_M, (0, 1))


def _samples(radius_of_theta, n: int = 7201, clockwise: bool = False):
    """Stamps, positions on r(θ) and the reference velocity of one revolution from θ = 0."""
    sign = -1.0 if clockwise else 1.0
    theta = sign * np.linspace(0.0, 2 * np.pi, n)
    radius = radius_of_theta(theta)
    position = np.column_stack((radius * np.cos(theta), radius * np.sin(theta)))
    velocity = sign * np.column_stack((-np.sin(theta), np.cos(theta)))
    velocity[[0, -1]] = 0.0  # start and stop at rest
    return np.arange(n, dtype=np.int64) * 1_000_000, position, velocity


def test_circle_of_accepts_one_circle_and_refuses_the_rest(synth) -> None:
    assert circle_of(synth.circle_program()) == Circle((0.0, 0.0), R_M, (0, 1))
    assert circle_of(synth.corner_program()) is None
    half = [ArcSegment(start_m=np.array(a), end_m=np.array(b), center_m=np.zeros(2), clockwise=False, feed_m_s=0.01)
            for a, b in (([R_M, 0.0], [-R_M, 0.0]), ([-R_M, 0.0], [R_M, 0.0]))]
    assert circle_of(Program(name="halves", axis_names=AXES, segments=tuple(half))) == _circle()
    other = ArcSegment(start_m=np.array([R_M, 0.0]), end_m=np.array([R_M + 0.02, 0.0]),
                       center_m=np.array([R_M + 0.01, 0.0]), clockwise=True, feed_m_s=0.01)
    assert circle_of(Program(name="s", axis_names=AXES, segments=(half[0], half[1], other))) is None


def test_least_squares_fit_recovers_an_offset_circle() -> None:
    theta = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    points = np.column_stack((0.003 + 0.015 * np.cos(theta), -0.002 + 0.015 * np.sin(theta)))
    centre, radius = fit_circle(points)
    assert_allclose(centre, (0.003, -0.002), atol=1e-14)
    assert_allclose(radius, 0.015, rtol=1e-12)


def test_constant_radius_error_is_the_mean_radius_error_with_no_deviation() -> None:
    stamps, position, velocity = _samples(lambda t: np.full_like(t, R_M - 4e-6))
    test = analyse_circle(_circle(), AXES, stamps, position, velocity)
    assert_allclose(test.mean_radius_error_m, -4e-6, rtol=1e-9)
    assert_allclose([test.radial_deviation_min_m, test.radial_deviation_max_m], -4e-6, rtol=1e-9)
    assert test.circular_deviation_m < 1e-12 and test.circular_deviation_nominal_m < 1e-12


def test_oval_path_gives_circular_deviation_twice_its_amplitude() -> None:
    stamps, position, velocity = _samples(lambda t: R_M + 3e-6 * np.cos(2 * t))
    test = analyse_circle(_circle(), AXES, stamps, position, velocity)
    assert_allclose(test.circular_deviation_m, 6e-6, rtol=1e-3)
    assert_allclose(test.circular_deviation_nominal_m, 6e-6, rtol=1e-6)
    assert abs(test.mean_radius_error_m) < 1e-9


def test_a_centre_offset_shows_about_the_nominal_centre_but_not_about_the_lsq_centre() -> None:
    offset_m = 5e-6
    theta = np.linspace(0.0, 2 * np.pi, 3601)
    position = np.column_stack((offset_m + R_M * np.cos(theta), R_M * np.sin(theta)))
    velocity = np.column_stack((-np.sin(theta), np.cos(theta)))
    test = analyse_circle(_circle(), AXES, np.arange(theta.size, dtype=np.int64), position, velocity)
    assert_allclose(test.circular_deviation_nominal_m, 2 * offset_m, rtol=1e-3)
    assert test.circular_deviation_m < 1e-10
    assert_allclose(test.lsq_center_m, (offset_m, 0.0), atol=1e-12)


@pytest.mark.parametrize("clockwise", [False, True])
def test_reversal_spikes_are_found_at_the_quadrants_with_their_height(clockwise: bool) -> None:
    height_m, base_m = 6e-6, -2e-6
    spike_at = math.pi / 2 if not clockwise else -math.pi / 2  # where y reverses first

    def radius(theta: np.ndarray) -> np.ndarray:
        return R_M + base_m + height_m * np.exp(-(((theta - spike_at) / 0.02) ** 2))

    stamps, position, velocity = _samples(radius, clockwise=clockwise)
    test = analyse_circle(_circle(), AXES, stamps, position, velocity, window_deg=10.0)
    found = [(r.axis_name, round(r.angle_deg)) for r in test.reversals]
    expected = [("y", 90), ("x", 180), ("y", 270)] if not clockwise else [("y", 270), ("x", 180), ("y", 90)]
    assert found == expected
    mean = test.mean_radius_error_m
    assert_allclose(test.reversals[0].peak_radial_deviation_m, base_m + height_m, rtol=1e-6)
    assert_allclose(test.reversals[0].spike_m, base_m + height_m - mean, rtol=1e-6)
    assert all(abs(r.peak_radial_deviation_m - base_m) < 1e-9 for r in test.reversals[1:])


def test_reversal_indices_ignore_rest_and_small_noise() -> None:
    velocity = np.array([0.0, 1e-6, 0.5, 1.0, 0.4, 0.0, -1e-7, -0.6, -1.0, 0.0, 0.0])
    assert_array_equal(reversal_indices(velocity), [7])
    assert reversal_indices(np.zeros(5)).size == 0
    assert reversal_indices(np.full(4, np.nan)).size == 0


def test_window_outside_its_range_is_refused() -> None:
    stamps, position, velocity = _samples(lambda t: np.full_like(t, R_M), n=50)
    with pytest.raises(ConfigError, match=r"window_deg must be in \[0.0, 180.0\], got 400"):
        analyse_circle(_circle(), AXES, stamps, position, velocity, window_deg=400)


def test_score_of_a_circle_run_carries_the_circular_test(synth) -> None:
    score = score_run(synth.make_run(synth.circle_program(), synth.circle_trajectory(R_M, 2e-6, n=4000)))
    data = json.loads(score.to_json())["circular_test"]
    assert_allclose(data["mean_radius_error_um"], 2.0, rtol=1e-6)
    assert_allclose(data["mean_radius_error_blu"], 0.2, rtol=1e-6)
    assert [r["axis"] for r in data["reversals"]] == ["y", "x", "y"]
    assert "circular test (ISO 230-4)" in score.to_table()
    assert score_run(synth.make_run(synth.corner_program(),
                                    synth.offset_trajectory(synth.corner_program(), [0, 0]))).circular is None
