"""Estimators where the position leads the reference, and past the closing point of a closed program.

The window estimator is checked against the exact signed contour error on
generated constant-curvature paths (lines, arcs of either direction, a helix
in 3 axes) with the position lagging or leading the newest reference while
the program goes on; the path estimator on closed programs (a polygon, a
circle of four arcs) with the tool run past the closing point.
"""
from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_contour_control.estimators import make_estimator, signed_contour_error, signed_segment_error
from cnc_contour_control.estimators.window import ahead_error, line_error
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment, Program, Segment

T_S = 1e-3
#: The goal on the window estimator, leading as well as lagging: |estimate − exact| ≤ 1 µm.
GOAL_M = 1e-6


def _path(kind: str, radius_m: float, heading_rad: float, rise_m: float) -> Segment:
    """A line (60 mm) or an arc of 300° (ccw, cw; a helix rising ``rise_m`` in 3 axes) from the origin."""
    n = 3 if rise_m else 2
    start = np.zeros(n)
    direction = np.zeros(n)
    direction[:2] = math.cos(heading_rad), math.sin(heading_rad)
    if kind == "line":
        return LineSegment(start, start + 0.06 * direction, 0.05)
    turn = 1.0 if kind == "ccw" else -1.0
    normal = np.zeros(n)
    normal[:2] = -turn * direction[1], turn * direction[0]
    center = start + radius_m * normal
    angle = math.radians(300.0) * turn
    rotated = np.zeros(n)
    offset = start[:2] - center[:2]
    rotated[:2] = center[:2] + [offset[0] * math.cos(angle) - offset[1] * math.sin(angle),
                                offset[0] * math.sin(angle) + offset[1] * math.cos(angle)]
    if rise_m:
        rotated[2] = rise_m
    return ArcSegment(start, rotated, center, kind == "cw", (0, 1), 0.05)


def _stream(segment: Segment, feed_m_s: float, lead_m: float, offset_m: float) -> tuple[np.ndarray, np.ndarray,
                                                                                          np.ndarray]:
    """References at 1 kHz along ``segment``; positions ``lead_m`` along (< 0 behind) and ``offset_m`` to the left.

    Returns references and positions (M, n) and which samples to judge: three references stored and the
    position's nearest point inside the segment (not before its start, not past its end).
    """
    s_ref = np.arange(0.0, segment.length_m - max(lead_m, 0.0) - 1e-4, feed_m_s * T_S)
    s_pos = np.clip(s_ref + lead_m, 0.0, segment.length_m)
    refs, points, tangents = segment.point(s_ref), segment.point(s_pos), segment.tangent(s_pos)
    normal = np.zeros_like(tangents)
    normal[:, 0], normal[:, 1] = -tangents[:, 1], tangents[:, 0]
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    judged = (np.arange(s_ref.size) >= 3) & (s_ref + lead_m > 1e-4)
    return refs, points + offset_m * normal, judged


@settings(max_examples=40, deadline=None)
@given(kind=st.sampled_from(["line", "ccw", "cw", "helix"]), radius_mm=st.floats(2.0, 50.0),
       heading_deg=st.floats(-180.0, 180.0), feed_mm_min=st.floats(300.0, 6000.0),
       lead_mm=st.floats(-2.0, 1.0), offset_um=st.floats(-300.0, 300.0))
def test_window_within_1_um_leading_and_lagging(kind: str, radius_mm: float, heading_deg: float,
                                                feed_mm_min: float, lead_mm: float, offset_um: float) -> None:
    rise_m = 0.003 if kind == "helix" else 0.0
    segment = _path("ccw" if kind == "helix" else kind, radius_mm * 1e-3, math.radians(heading_deg), rise_m)
    program = Program("generated", ("x", "y", "z")[:segment.n_axes], (segment,))
    refs, positions, judged = _stream(segment, feed_mm_min / 60e3, lead_mm * 1e-3, offset_um * 1e-6)
    estimator = make_estimator("window", {}, program)
    estimates = [estimator.step(r, p) for r, p in zip(refs.tolist(), positions.tolist())]
    found = np.array([e.contour_error_m for e in estimates])
    exact, _, _ = signed_contour_error(program, positions)
    worst = float(np.max(np.abs(found - exact)[judged]))
    assert worst <= GOAL_M, f"{kind}: |estimate − exact| {worst * 1e6:.3f} µm > 1 µm"
    _, _, _, tangent_rad = signed_segment_error(segment, positions)
    ahead = judged & (lead_mm > 0.05)  # clearly past the newest reference: the tangent's angle at the nearest point
    turn = np.angle(np.exp(1j * (np.array([e.angle_rad for e in estimates]) - tangent_rad)))
    assert np.all(np.abs(turn[ahead]) < 1e-6)


def test_ahead_on_a_line_is_the_line_and_continues_the_chord_sign() -> None:
    newest, middle, first = (0.002, 0.001), (0.001, 0.0005), (0.0, 0.0)
    for pos in ((0.004, 0.0025), (0.003, 0.0011), (0.0025, 0.0008)):
        found = ahead_error(pos, first, middle, newest, (0, 1))
        assert found is not None
        line, line_angle = line_error(pos, newest, middle, newest, (0, 1))
        assert math.isclose(found[0], line, abs_tol=1e-15) and math.isclose(found[1], line_angle, abs_tol=1e-12)
    assert ahead_error((0.0019, 0.0012), first, middle, newest, (0, 1)) is None  # not past the newest point


def _closed(kind: str) -> Program:
    """A 20 mm square (4 lines) or a circle of r = 10 mm as four quarter arcs, both closed, ccw from the origin."""
    if kind == "square":
        corners = [np.array(c) * 0.02 for c in ((0, 0), (1, 0), (1, 1), (0, 1), (0, 0))]
        return Program("square", ("x", "y"), tuple(LineSegment(a, b, 0.05) for a, b in zip(corners, corners[1:])))
    center = np.array([0.0, 0.01])
    points = [center + 0.01 * np.array([math.sin(q * math.pi / 2), -math.cos(q * math.pi / 2)]) for q in range(5)]
    points[4] = points[0]
    return Program("quarters", ("x", "y"), tuple(ArcSegment(a, b, center, False, (0, 1), 0.05)
                                                 for a, b in zip(points, points[1:])))


@given(kind=st.sampled_from(["square", "quarters"]), past_mm=st.floats(0.5, 3.0), offset_um=st.floats(-150, 150))
@settings(max_examples=12, deadline=None)
def test_path_estimator_past_the_closing_point_of_a_closed_program(kind: str, past_mm: float,
                                                                   offset_um: float) -> None:
    program = _closed(kind)
    length = program.total_length_m
    s_all = np.arange(0.0, length + past_mm * 1e-3, 1e-4)
    wrapped = np.mod(s_all, length)
    index = np.clip(np.searchsorted(program.segment_start_m, wrapped, side="right") - 1, 0, 3)
    positions = np.zeros((s_all.size, 2))
    for i in range(4):
        rows = index == i
        local = wrapped[rows] - program.segment_start_m[i]
        tangent = program.segments[i].tangent(local)
        positions[rows] = program.segments[i].point(local) + offset_um * 1e-6 * np.c_[-tangent[:, 1], tangent[:, 0]]
    estimator = make_estimator("path", {}, program)
    end = program.end_m.tolist()
    found = np.array([estimator.step(end, p).contour_error_m for p in positions.tolist()])
    exact, _, _ = signed_contour_error(program, positions)
    past = s_all > length
    assert np.max(np.abs(np.abs(found) - np.abs(exact))[past]) < 1e-12
    clear = s_all > length + abs(offset_um) * 1e-6 + 1e-5  # clear of the closing vertex (a tie there signs either way)
    assert np.max(np.abs(found - exact)[clear]) < 1e-12
    assert np.allclose(exact[clear], offset_um * 1e-6, atol=1e-12)  # the truth: the offset from the contour
