"""The blending bench's pieces: the toppra time-optimal reference and the corpus."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_contour_control.motion.geometry import LineSegment, Program
from cnc_contour_control.motion.interpolation import AxisLimits, Interpolator, InterpolatorConfig
from cnc_tools.bench.blending import limit_ratios, limits_for, planning_cost, worst_deviation_m
from cnc_tools.bench.blending_corpus import CORPUS, arc_chain, polygon, true_circle
from cnc_tools.bench.time_optimal import ProgramPath, time_optimal_s

LIMITS = AxisLimits((0.035, 0.035), (0.5, 0.5))


def test_toppra_finds_the_trapezoid_of_one_line() -> None:
    """A 50 mm line at 20 mm/s and 0.5 m/s^2: L/F + F/a = 2.54 s, also what our planner gives."""
    line = Program("l", ("x", "y"), (LineSegment([0.0, 0.0], [0.05, 0.0], 0.02),))
    assert time_optimal_s(line, LIMITS, 1e-4) == pytest.approx(0.05 / 0.02 + 0.02 / 0.5, rel=1e-4)


def test_toppra_on_the_circle_is_faster_than_our_half_budget_arc() -> None:
    """Our arcs keep half the acceleration for the centripetal part; the optimum uses all of it."""
    circle = true_circle()
    ours = Interpolator(circle, limits_for(circle)).duration_s
    optimum = time_optimal_s(circle, limits_for(circle), 2e-4)
    assert optimum < ours < math.sqrt(2.0) * optimum * 1.05


def test_program_path_derivatives_are_the_segments_frames() -> None:
    program = polygon(6)
    path = ProgramPath(program)
    s = np.linspace(0.0, program.total_length_m, 50)
    step = 1e-7
    assert np.allclose((path(s + step) - path(s - step))[1:-1, :-1] / (2 * step), path(s, 1)[1:-1, :-1], atol=1e-5)
    assert np.all(path(s, 1)[:, -1] == 1.0)


def test_corpus_programs_plan_within_limits_and_tolerance() -> None:
    assert {"circle-36-gon", "star-5", "pocket", "arc-chain", "raster-3axis"} <= set(CORPUS)
    for program in (polygon(36), arc_chain()):
        interpolator = Interpolator(program, limits_for(program), InterpolatorConfig(path_tolerance_mm=0.01))
        velocity, acceleration = limit_ratios(interpolator)
        assert np.all(velocity <= 1 + 1e-9) and np.all(acceleration <= 1 + 1e-9)
        assert worst_deviation_m(interpolator) <= 1e-5 * (1 + 1e-9)


def test_a_square_is_four_rest_to_rest_lines_for_toppra() -> None:
    points = np.array([[0.0, 0.0], [0.01, 0.0], [0.01, 0.01], [0.0, 0.01], [0.0, 0.0]])
    square = Program("square", ("x", "y"), tuple(LineSegment(points[i], points[i + 1], 0.02) for i in range(4)))
    assert time_optimal_s(square, LIMITS, 1e-4) == pytest.approx(4 * (0.01 / 0.02 + 0.02 / 0.5), rel=1e-4)
    assert Interpolator(square, LIMITS).duration_s == pytest.approx(4 * (0.01 / 0.02 + 0.02 / 0.5))


def test_planning_cost_per_segment_does_not_grow_with_the_program() -> None:
    """CPU per segment of a 10x longer polygon within 3x (it is flat; 3x absorbs a loaded machine)."""
    short, long = planning_cost((500, 5000))
    assert long["segments"] == 5000 and long["load_1min"] >= 0.0
    assert long["us_per_segment"] < 3.0 * short["us_per_segment"]
