"""Core maths of contour geometry: segments, nearest points, the program's contour distance."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial import cKDTree

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment, Program
from cnc_contour_control.motion.points import RADIUS_TOLERANCE_M

FEED_M_S = 0.01


def quarter_arc(clockwise: bool = False) -> ArcSegment:
    """r = 20 mm centred at (0, 0.02), from the origin a quarter turn either way."""
    end = [-0.02, 0.02] if clockwise else [0.02, 0.02]
    return ArcSegment([0.0, 0.0], end, [0.0, 0.02], clockwise, (0, 1), FEED_M_S)


def helix() -> ArcSegment:
    """A 3/4 turn in XY (r = 10 mm) rising 5 mm in Z, clockwise."""
    return ArcSegment([0.01, 0.0, 0.0], [0.0, 0.01, 0.005], [0.0, 0.0, 0.0], True, (0, 1), FEED_M_S)


SEGMENTS = {
    "line2": LineSegment([0.0, 0.0], [0.03, 0.01], FEED_M_S),
    "line3": LineSegment([0.0, 0.01, -0.01], [0.02, -0.01, 0.02], FEED_M_S),
    "arc_ccw": quarter_arc(False),
    "arc_cw": quarter_arc(True),
    "full_circle": ArcSegment([0.0, 0.0], [0.0, 0.0], [0.0, 0.02], False, (0, 1), FEED_M_S),
    "arc_zx": ArcSegment([0.0, 0.0, 0.0], [0.01, 0.003, 0.01], [0.0, 0.003, 0.01], False, (2, 0), FEED_M_S),
    "helix": helix(),
}


def dense(segment: LineSegment | ArcSegment, count: int = 200_001) -> np.ndarray:
    return segment.point(np.linspace(0.0, segment.length_m, count))


@pytest.mark.parametrize("name", sorted(SEGMENTS))
def test_tangent_is_unit_and_the_derivative_of_point(name: str) -> None:
    segment = SEGMENTS[name]
    s = np.linspace(0.01, 0.99, 7) * segment.length_m
    h = 1e-6
    derivative = (segment.point(s + h) - segment.point(s - h)) / (2 * h)
    assert_allclose(np.linalg.norm(segment.tangent(s), axis=1), 1.0, rtol=1e-12)
    assert_allclose(segment.tangent(s), derivative, atol=1e-7)


@pytest.mark.parametrize("name", sorted(SEGMENTS))
def test_curvature_vector_is_the_second_derivative_of_point(name: str) -> None:
    segment = SEGMENTS[name]
    s = np.linspace(0.05, 0.95, 5) * segment.length_m
    h = 1e-4
    second = (segment.point(s + h) - 2 * segment.point(s) + segment.point(s - h)) / h**2
    assert_allclose(segment.curvature_vector(s), second, atol=1e-4 * max(1.0, np.abs(second).max()))


@pytest.mark.parametrize("name", sorted(SEGMENTS))
def test_frame_matches_the_vectorised_methods(name: str) -> None:
    segment = SEGMENTS[name]
    s = 0.37 * segment.length_m
    point, tangent, curvature = segment.frame(s)
    assert_allclose(point, segment.point(s), atol=1e-15)
    assert_allclose(tangent, segment.tangent(s), atol=1e-15)
    assert_allclose(curvature, segment.curvature_vector(s), atol=1e-12)


@pytest.mark.parametrize("name", sorted(SEGMENTS))
def test_end_points_and_length(name: str) -> None:
    segment = SEGMENTS[name]
    path = dense(segment, 100_001)
    polyline = np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1))
    assert_allclose(segment.point(0.0), segment.start_m, atol=1e-15)
    assert_allclose(segment.point(segment.length_m), segment.end_m, atol=1e-15)
    assert_allclose(segment.length_m, polyline, rtol=1e-8)


@pytest.mark.parametrize("clockwise, tangent_x", [(False, 1.0), (True, -1.0)])
def test_arc_direction_and_curvature_toward_the_centre(clockwise: bool, tangent_x: float) -> None:
    arc = quarter_arc(clockwise)
    assert_allclose(arc.length_m, 0.02 * math.pi / 2)
    assert_allclose(arc.tangent(0.0), [tangent_x, 0.0], atol=1e-15)
    assert_allclose(arc.curvature_vector(0.0), [0.0, 50.0], atol=1e-12)


def test_full_circle_sweeps_two_pi() -> None:
    circle = SEGMENTS["full_circle"]
    assert circle.sweep_rad == pytest.approx(2 * math.pi)
    assert circle.length_m == pytest.approx(2 * math.pi * 0.02)
    assert_allclose(circle.point(circle.length_m / 2), [0.0, 0.04], atol=1e-15)


def test_helix_curvature_is_the_exact_helix_curvature() -> None:
    arc = helix()
    rise_per_rad = 0.005 / (1.5 * math.pi)
    expected = 0.01 / (0.01**2 + rise_per_rad**2)
    assert_allclose(np.linalg.norm(arc.curvature_vector(0.3 * arc.length_m)), expected, rtol=1e-12)


@pytest.mark.parametrize("name", sorted(SEGMENTS))
def test_max_abs_tangent_and_curvature_bound_dense_samples(name: str) -> None:
    segment = SEGMENTS[name]
    s = np.linspace(0.0, segment.length_m, 20_001)
    assert_allclose(segment.max_abs_tangent(), np.abs(segment.tangent(s)).max(axis=0), atol=1e-7)
    assert_allclose(segment.max_abs_curvature_per_m(), np.abs(segment.curvature_vector(s)).max(axis=0),
                    rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("name", sorted(SEGMENTS))
def test_nearest_matches_dense_sampling(name: str) -> None:
    segment = SEGMENTS[name]
    rng = np.random.default_rng(7)
    low, high = segment.bounding_box_m()
    points = rng.uniform(low - 0.01, high + 0.01, size=(200, segment.n_axes))
    distance, s = segment.nearest(points)
    brute, _ = cKDTree(dense(segment)).query(points)
    spacing = segment.length_m / 200_000
    assert np.all(distance <= brute + 1e-12)
    assert np.all(brute - distance <= spacing)
    assert_allclose(np.linalg.norm(points - segment.point(s), axis=1), distance, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("point, expected_m, expected_s_m", [
    ([0.0, 0.02], 0.02, None),  # the centre: every arc point is at r
    ([0.0, -0.01], 0.01, 0.0),  # before the start, nearest is the start
    ([0.03, 0.02], 0.01, 0.02 * math.pi / 2),  # beyond the end, on its radius
    ([-0.02, 0.0], math.hypot(0.02, 0.0), 0.0),  # outside the sweep, start closer than end
    ([0.02 * math.cos(-math.pi / 4) * 1.5, 0.02 + 0.02 * math.sin(-math.pi / 4) * 1.5], 0.01, 0.02 * math.pi / 4),
])
def test_planar_arc_nearest_is_exact(point: list[float], expected_m: float, expected_s_m: float | None) -> None:
    distance, s = quarter_arc().nearest(np.array([point]))
    assert_allclose(distance, [expected_m], rtol=1e-12)
    if expected_s_m is not None:
        assert_allclose(s, [expected_s_m], atol=1e-12)


def test_line_nearest_clamps_to_the_end_points() -> None:
    line = LineSegment([0.0, 0.0], [1.0, 0.0], FEED_M_S)
    distance, s = line.nearest(np.array([[0.5, 2.0], [-3.0, 4.0], [4.0, -4.0]]))
    assert_allclose(distance, [2.0, 5.0, 5.0])
    assert_allclose(s, [0.5, 0.0, 1.0])


@pytest.mark.parametrize("kwargs, message", [
    ({"end_m": [0.0201, 0.02]}, "end radius 0.0201 m, start radius 0.02 m"),
    ({"end_m": [0.02, 0.02], "center_m": [0.0, 0.0]}, "radius_m must be > 0"),
    ({"plane": (0, 0)}, "plane must be two distinct axis indices"),
    ({"plane": (0, 2)}, "plane must be two distinct axis indices"),
    ({"feed_m_s": 0.0}, "feed_m_s must be > 0, got 0.0"),
    ({"end_m": [0.02, math.nan]}, "end_m must be finite"),
    ({"center_m": [0.0, 0.02, 0.0]}, "center_m must have 2 entries"),
    ({"clockwise": "cw"}, "clockwise must be a bool"),
])
def test_bad_arcs_are_refused(kwargs: dict, message: str) -> None:
    args = {"start_m": [0.0, 0.0], "end_m": [0.02, 0.02], "center_m": [0.0, 0.02],
            "clockwise": False, "plane": (0, 1), "feed_m_s": FEED_M_S}
    args.update(kwargs)
    with pytest.raises(ProgramError, match=message):
        ArcSegment(**args)


def test_arc_end_off_circle_names_both_radii_and_the_tolerance() -> None:
    with pytest.raises(ProgramError) as info:
        ArcSegment([0.0, 0.0], [0.0200024, 0.02], [0.0, 0.02], False, (0, 1), FEED_M_S)
    text = str(info.value)
    assert "start radius 0.02 m" in text and "end radius 0.0200024 m" in text
    assert f"tolerance {RADIUS_TOLERANCE_M} m" in text


def test_arc_end_within_tolerance_is_accepted() -> None:
    arc = ArcSegment([0.0, 0.0], [0.0200015, 0.02], [0.0, 0.02], False, (0, 1), FEED_M_S)
    assert_allclose(arc.point(arc.length_m), [0.02, 0.02], atol=1e-15)


@pytest.mark.parametrize("start, end, feed, message", [
    ([0.0, 0.0], [0.0, 0.0], FEED_M_S, "length_m must be >="),
    ([0.0, 0.0], [1.0, 0.0, 0.0], FEED_M_S, "end_m must have 2 entries"),
    ([[0.0, 0.0]], [1.0, 0.0], FEED_M_S, "start_m must be a 1-D array"),
    ([0.0, 0.0], [1.0, 0.0], -1.0, "feed_m_s must be > 0, got -1.0"),
    ([0.0, math.inf], [1.0, 0.0], FEED_M_S, "start_m must be finite"),
])
def test_bad_lines_are_refused(start: list, end: list, feed: float, message: str) -> None:
    with pytest.raises(ProgramError, match=message):
        LineSegment(start, end, feed)


def test_program_refuses_a_gap_naming_the_segment() -> None:
    first = LineSegment([0.0, 0.0], [0.01, 0.0], FEED_M_S)
    second = LineSegment([0.01, 0.0], [0.01, 0.01], FEED_M_S)
    third = LineSegment([0.01, 0.0105], [0.0, 0.02], FEED_M_S)
    with pytest.raises(ProgramError,
                       match=r"segment 2: .* 0.0005 m from the end of segment 1 .*; contiguity tolerance is 1e-06 m"):
        Program("gap", ("x", "y"), (first, second, third))


@pytest.mark.parametrize("axes, segments, message", [
    (("x", "y"), (), "has no segments"),
    (("x", "x"), (LineSegment([0, 0], [1, 0], FEED_M_S),), "axis_names must be distinct"),
    (("x", "y", "z"), (LineSegment([0, 0], [1, 0], FEED_M_S),), "segment 0: has 2 axes, the program has 3"),
])
def test_program_refuses_bad_structure(axes: tuple, segments: tuple, message: str) -> None:
    with pytest.raises(ProgramError, match=message):
        Program("bad", axes, segments)


def star_program(n_segments: int = 30) -> Program:
    """A closed polygon of lines and arcs in 3 axes (planar arcs and helices)."""
    rng = np.random.default_rng(3)
    point = np.zeros(3)
    segments = []
    for k in range(n_segments):
        angle = 2 * math.pi * k / n_segments
        if k % 3 == 2:
            center = point + 0.005 * np.array([math.cos(angle), math.sin(angle), 0.0])
            end = center.copy()
            end[:2] += 0.005 * np.array([math.cos(angle + 1.0), math.sin(angle + 1.0)])
            end[2] = point[2] + rng.uniform(-0.001, 0.001) * (k % 2)
            segments.append(ArcSegment(point, end, center, bool(k % 2), (0, 1), FEED_M_S))
        else:
            end = point + 0.01 * np.array([math.cos(angle), math.sin(angle), rng.uniform(-0.1, 0.1)])
            segments.append(LineSegment(point, end, FEED_M_S))
        point = segments[-1].end_m
    return Program("star", ("x", "y", "z"), tuple(segments))


def test_contour_distance_is_the_minimum_over_segments() -> None:
    program = star_program()
    points = np.random.default_rng(1).uniform(-0.05, 0.05, size=(500, 3))
    distance, index = program.contour_distance(points)
    per_segment = np.array([segment.nearest(points)[0] for segment in program.segments])
    assert_allclose(distance, per_segment.min(axis=0), rtol=1e-12)
    assert_allclose(per_segment[index, np.arange(points.shape[0])], distance, rtol=1e-12)


def test_contour_distance_on_the_contour_is_zero() -> None:
    program = star_program()
    s = np.linspace(0.0, 1.0, 11)
    points = np.vstack([segment.point(s * segment.length_m) for segment in program.segments])
    distance, _ = program.contour_distance(points)
    assert_allclose(distance, 0.0, atol=1e-9)


def test_contour_distance_is_fast() -> None:
    program = star_program(30)
    s = np.linspace(0.0, program.total_length_m, 60_000)
    points = np.vstack([program.segments[0].point(0.0)] * 60_000)
    index = np.searchsorted(program.segment_start_m, s, side="right") - 1
    for i, segment in enumerate(program.segments):
        rows = index == i
        points[rows] = segment.point(s[rows] - program.segment_start_m[i])
    points += np.random.default_rng(2).normal(scale=2e-5, size=points.shape)
    distance, _ = program.contour_distance(points)
    assert distance.shape == (60_000,) and distance.max() < 2e-4  # the noise added (speed: bench scoring)
