"""The blending bench's pieces: the toppra time-optimal reference and the corpus."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import LineSegment, Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_tools.bench.blending import goals, planning_cost, program_figures
from cnc_tools.bench.blending_corpus import CORPUS, arc_chain, arc_scallops, polygon, ramps_3axis, true_circle, zigzag
from cnc_tools.bench.blending_limits import (
    BEST_OPTIONS,
    JERK_STRIDE,
    MAX_ACCELERATION_M_S2,
    MAX_JERK_M_S3,
    MAX_VELOCITY_M_S,
    limit_ratios,
    limits_for,
    sampled_ratios,
    worst_deviation_m,
)
from cnc_tools.bench.blending_override import SCHEDULES, sweep_figures
from cnc_tools.bench.time_optimal import ProgramPath, time_optimal_s

LIMITS = AxisLimits((0.035, 0.035), (0.5, 0.5))


def test_toppra_finds_the_trapezoid_of_one_line() -> None:
    """A 50 mm line at 20 mm/s and 0.5 m/s^2: L/F + F/a = 2.54 s, also what our planner gives."""
    line = Program("l", ("x", "y"), (LineSegment([0.0, 0.0], [0.05, 0.0], 0.02),))
    assert time_optimal_s(line, LIMITS, 1e-4) == pytest.approx(0.05 / 0.02 + 0.02 / 0.5, rel=1e-4)


def test_toppra_on_the_circle_is_faster_than_our_half_budget_arc() -> None:
    """The split budget keeps half the acceleration for the centripetal part; the optimum uses all of it."""
    circle = true_circle()
    split = InterpolatorConfig(arc_combined_budget=False, arc_centripetal_fraction=0.5)
    ours = Interpolator(circle, limits_for(circle), split).duration_s
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


def test_the_shipped_planner_defaults_are_the_bench_s_best_options() -> None:
    defaults = InterpolatorConfig()
    assert {name: getattr(defaults, name) for name in BEST_OPTIONS} == BEST_OPTIONS


def test_sampled_ratios_find_a_cubic_s_jerk_and_an_acceleration_step() -> None:
    """p = j t^3 / 6 on x: jerk j from the acceleration's and the positions' differences; a step in a: a / dt."""
    dt_s, jerk = 1e-3, 0.5 * MAX_JERK_M_S3
    t = np.arange(0.0, 0.04, dt_s)
    position = np.c_[jerk * t**3 / 6.0, np.zeros_like(t)]
    velocity, acceleration = np.c_[jerk * t**2 / 2.0, 0 * t], np.c_[jerk * t, 0 * t]
    ratios = sampled_ratios(position, velocity, acceleration, dt_s, 2)
    assert ratios["jerk_ratio"] == pytest.approx([0.5, 0.0], abs=1e-6)
    assert ratios["velocity_ratio"][0] == pytest.approx(jerk * t[-1] ** 2 / 2.0 / MAX_VELOCITY_M_S)
    step = np.c_[np.where(t >= 0.02, 0.5 * MAX_ACCELERATION_M_S2, 0.0), 0 * t]
    stepped = sampled_ratios(np.zeros_like(position), np.zeros_like(position), step, dt_s, 2)
    assert stepped["jerk_ratio"][0] == pytest.approx(0.5 * MAX_ACCELERATION_M_S2 / dt_s / MAX_JERK_M_S3)
    assert JERK_STRIDE * dt_s <= 0.004  # the positions' third difference spans 4 ms at most


def test_the_zigzag_turns_by_150_degrees_and_the_ramps_move_three_axes() -> None:
    program = zigzag()
    u = np.array([segment.unit_vector for segment in program.segments])
    turns = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", u[:-1], u[1:]), -1, 1)))
    assert turns == pytest.approx(np.full(len(u) - 1, 150.0))
    ramps = ramps_3axis()
    assert ramps.n_axes == 3 and np.all(np.abs(ramps.segments[0].unit_vector) > 0.0)


def test_goals_read_each_column() -> None:
    figures = {"program": "pocket", "deviation_over_p": 1.0, "velocity_ratio": [0.6], "acceleration_ratio": [1.0],
               "jerk_ratio": [3.0], "cycle_s": 10.0, "exact_stop_s": 9.0, "toppra_s": 9.0}
    assert goals(figures) == {"deviation": True, "v, a": True, "jerk": False, "<= G61": False, "toppra": True}
    assert goals({**figures, "program": "star-5"})["toppra"] is None


def test_the_bench_plans_as_shipped_with_the_jerk_limit_against_a_jerk_limited_exact_stop() -> None:
    """A 6-gon: fir (the default) with the jerk limit holds it and P; G61 with it is scurve, slower than without."""
    figures = program_figures(polygon(6), 2e-4)
    assert figures["jerk_mode_used"] == "fir" and figures["exact_stop_mode"] == "scurve"
    assert figures["exact_stop_s"] > figures["exact_stop_no_jerk_s"]
    assert 0.5 < max(figures["jerk_ratio"]) <= 1.0 + 1e-9
    assert all(met is not False for met in goals(figures).values())


def test_the_override_sweep_holds_the_tolerance_and_the_limits_on_a_short_zigzag() -> None:
    """Requests changed mid-path from 100 % to 200 %, 10 %, 150 %, 50 %, 200 % on a 4-segment zig-zag."""
    figures = sweep_figures(zigzag(segments=4, length_m=0.002), "changes mid-path")
    assert SCHEDULES["changes mid-path"][1] == (1.0, 2.0, 0.1, 1.5, 0.5, 2.0)
    assert figures["deviation_over_p"] <= 1.0 + 1e-9
    assert max(figures["velocity_ratio"] + figures["acceleration_ratio"]) <= 1.0 + 1e-9
    assert figures["cycle_s"] > 0.5


def test_the_override_sweep_measures_the_filtered_ticks_against_the_programmed_path() -> None:
    """90-degree arc-arc corners at 200 % through the jerk filter: within P of the programmed arcs (measured against
    the segment each tick's index names, the filter's lag read as 1.2 P)."""
    figures = sweep_figures(arc_scallops(radii_m=(5e-4, 1e-3), repeats=2), "200 %")
    assert 0.5 < figures["deviation_over_p"] <= 1.0 + 1e-9
    assert max(figures["velocity_ratio"] + figures["acceleration_ratio"] + figures["jerk_ratio"]) <= 1.0 + 1e-9
