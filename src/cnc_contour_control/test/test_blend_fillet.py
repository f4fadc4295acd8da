"""Fillets of line-arc and arc-arc corners: the fast measurement against ``Segment.nearest`` and the old search."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnc_contour_control.motion import blend_fillet as bf
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.geometry import LineSegment, Segment

FEED_M_S = 0.02
LINE_M = 0.01


def _rotate(vector: np.ndarray, angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1]])


def _arc_from(start: np.ndarray, tangent: np.ndarray, radius_m: float, ccw: bool, sweep_rad: float,
              backwards: bool) -> ArcSegment:
    """An arc through ``start`` with ``tangent`` there: starting there, or (``backwards``) ending there."""
    turn = 1.0 if ccw else -1.0
    center = start + turn * radius_m * np.array([-tangent[1], tangent[0]])
    other = center + _rotate(start - center, (-turn if backwards else turn) * sweep_rad)
    ends = (other, start) if backwards else (start, other)
    return ArcSegment(ends[0], ends[1], center, not ccw, (0, 1), FEED_M_S)


def corner(kind: str, turn_rad: float, side: float, radii_m: tuple[float, float], ccw: tuple[bool, bool],
           sweep_rad: float) -> tuple[Segment, Segment]:
    """A corner at the origin turning ``side`` (+1 left) by ``turn_rad``; ``kind`` 'line-arc', 'arc-line', 'arc-arc'."""
    origin, t1 = np.zeros(2), np.array([1.0, 0.0])
    t2 = _rotate(t1, side * turn_rad)
    before: Segment = LineSegment(-LINE_M * t1, origin, FEED_M_S) if kind == "line-arc" else \
        _arc_from(origin, t1, radii_m[0], ccw[0], sweep_rad, backwards=True)
    after: Segment = LineSegment(origin, LINE_M * t2, FEED_M_S) if kind == "arc-line" else \
        _arc_from(origin, t2, radii_m[1], ccw[1], sweep_rad, backwards=False)
    return before, after


def _reference_plan_fillet(before: Segment, after: Segment, tolerance_m: float,
                           turn_rad: float) -> bf.CornerFillet | None:
    """The search as it was before the fast measurement: ``deviation_m`` (``Segment.nearest``) at every step."""
    plane = bf.common_plane(before, after)
    if plane is None:
        return None
    corner_m = after.start_m
    t1, t2 = before.tangent(before.length_m)[list(plane)], after.tangent(0.0)[list(plane)]
    side = 1.0 if t1[0] * t2[1] - t1[1] * t2[0] > 0.0 else -1.0
    first, second = bf.carrier(before, plane, corner_m[list(plane)]), bf.carrier(after, plane, corner_m[list(plane)])
    limits = (bf.max_trim_m(before), bf.max_trim_m(after))
    if min(limits) <= 0.0:
        return None
    high = bf._MAX_RADIUS_PER_TRIM * max(limits)
    radius, low = min(tolerance_m / (1.0 / math.cos(0.5 * turn_rad) - 1.0), 0.5 * high), 0.0
    best: bf.CornerFillet | None = None
    for _ in range(bf._ITERATIONS):
        shape = bf.fillet(first, second, corner_m[list(plane)], side, radius)
        factor = bf._shrunk(shape, limits)
        if factor is not None:
            high, radius = radius, max(radius * factor, 0.5 * (low + radius))
            continue
        assert shape is not None
        deviation = bf.deviation_m(before, after, shape, plane, corner_m, side)
        if deviation > tolerance_m:
            high, radius = radius, max(radius * bf._AIM * tolerance_m / deviation, 0.5 * (low + radius))
            continue
        best, low = bf.CornerFillet(shape, plane, side, deviation), radius
        if deviation >= bf._CLOSE_ENOUGH * tolerance_m or high <= radius * 1.001:
            break
        radius = min(radius * bf._AIM * tolerance_m / max(deviation, 1e-300), bf._MAX_STEP * radius,
                     0.5 * (radius + high))
    return best


def dense_deviation_m(before: Segment, after: Segment, planned: bf.CornerFillet, samples: int = 4001) -> float:
    """Largest of the smaller ``Segment.nearest`` distance over ``samples`` points of the fillet (the oracle)."""
    shape = planned.shape
    a0, sweep = bf._fillet_angles(shape, planned.side)
    angle = a0 + planned.side * np.linspace(0.0, sweep, samples)
    points = shape.center + shape.radius_m * np.c_[np.cos(angle), np.sin(angle)]
    return float(np.max(np.minimum(before.nearest(points)[0], after.nearest(points)[0])))


#: Rounding of a deviation computed from positions of order 1 m (a femtometre).
ROUND_M = 1e-15

corners = st.builds(
    corner, st.sampled_from(["line-arc", "arc-line", "arc-arc"]), st.floats(math.radians(5), math.radians(170)),
    st.sampled_from([1.0, -1.0]), st.tuples(st.floats(5e-4, 0.04), st.floats(5e-4, 0.04)),
    st.tuples(st.booleans(), st.booleans()), st.floats(0.3, 2.5))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(corners, st.floats(1e-6, 5e-5))
def test_fast_fillet_is_within_tolerance_and_as_large_as_the_old_search(pair: tuple[Segment, Segment],
                                                                        tolerance_m: float) -> None:
    before, after = pair
    turn = float(np.arccos(np.clip(before.tangent(before.length_m) @ after.tangent(0.0), -1.0, 1.0)))
    planned, reference = bf.plan_fillet(before, after, tolerance_m, turn), \
        _reference_plan_fillet(before, after, tolerance_m, turn)
    assert (planned is None) == (reference is None)
    if planned is None or reference is None:
        return
    oracle = bf.deviation_m(before, after, planned.shape, planned.plane, np.zeros(2), planned.side)
    # brentq pins the crossing more closely than the old bounded search: never below it, at most a hair above;
    # ROUND_M: distances of ~1e-7 m taken as differences of ~0.5 m radii carry ~1e-17 m of rounding
    # (hypothesis found a corner 8e-18 m below: 2e-11 relative)
    assert oracle * (1.0 - 1e-12) - ROUND_M <= planned.deviation_m <= oracle * (1.0 + 1e-6)
    assert dense_deviation_m(before, after, planned) <= planned.deviation_m * (1.0 + 1e-12) + ROUND_M
    assert planned.deviation_m <= tolerance_m
    assert planned.shape.radius_m >= 0.99 * reference.shape.radius_m


@pytest.mark.parametrize("ccw", [True, False])
@pytest.mark.parametrize("sweep_rad", [0.4, 3.0, 5.5])
def test_piece_distance_is_segment_nearest(ccw: bool, sweep_rad: float) -> None:
    rng = np.random.default_rng(7)
    arc = _arc_from(np.array([0.001, 0.002]), np.array([0.6, 0.8]), 0.003, ccw, sweep_rad, backwards=False)
    line = LineSegment([0.001, 0.002], [0.004, -0.002], FEED_M_S)
    points = rng.uniform(-0.01, 0.01, size=(400, 2))
    for segment in (arc, line):
        piece = bf.Piece.of(segment, (0, 1))
        fast = [piece.distance_m(float(x), float(y)) for x, y in points]
        np.testing.assert_allclose(fast, segment.nearest(points)[0], rtol=1e-12, atol=1e-18)


def test_piece_distance_in_a_plane_of_three_axes() -> None:
    arc = ArcSegment([0.0, 0.003, 0.001], [0.003, 0.0, 0.001], [0.0, 0.0, 0.001], True, (1, 0), FEED_M_S)
    points = np.random.default_rng(3).uniform(-0.005, 0.005, size=(100, 3))
    points[:, 2] = 0.001
    piece = bf.Piece.of(arc, (1, 0))
    np.testing.assert_allclose([piece.distance_m(float(p[1]), float(p[0])) for p in points], arc.nearest(points)[0],
                               rtol=1e-12, atol=1e-18)


def test_corners_without_a_fillet_give_none() -> None:
    helix = ArcSegment([0.0, 0.0, 0.0], [0.002, 0.002, 0.001], [0.0, 0.002, 0.0], False, (0, 1), FEED_M_S)
    line = LineSegment([-0.01, 0.0, 0.0], [0.0, 0.0, 0.0], FEED_M_S)
    assert bf.plan_fillet(line, helix, 1e-5, math.pi / 4) is None
    tiny = ArcSegment([0.0, 0.0], [2e-6, 2e-6], [0.0, 2e-6], False, (0, 1), FEED_M_S)  # shorter than two fillets' rest
    assert bf.plan_fillet(LineSegment([-0.01, 0.0], [0.0, 0.0], FEED_M_S), tiny, 1e-5, 0.1) is None
    assert _reference_plan_fillet(LineSegment([-0.01, 0.0], [0.0, 0.0], FEED_M_S), tiny, 1e-5, 0.1) is None
