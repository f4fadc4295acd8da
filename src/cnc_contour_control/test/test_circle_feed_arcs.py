"""The circle shape's feed-in and feed-out arcs: a ballbar test's program (issue 26)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.geometry import ArcSegment
from cnc_contour_control.motion.program import load_program

R_MM = 10.0


def _circle(**options: float | str) -> list[ArcSegment]:
    program = load_program({"shape": "circle", "radius_mm": R_MM, "feed_mm_min": 600, **options})
    assert all(isinstance(s, ArcSegment) for s in program.segments)
    return [s for s in program.segments if isinstance(s, ArcSegment)]


def test_without_feed_arcs_the_circle_is_one_full_turn_from_the_start() -> None:
    (turn,) = _circle()
    np.testing.assert_array_equal(turn.start_m, [0.0, 0.0])
    np.testing.assert_array_equal(turn.end_m, turn.start_m)
    assert turn.length_m == pytest.approx(2 * math.pi * R_MM * 1e-3)


@pytest.mark.parametrize("direction", ["ccw", "cw"])
def test_feed_in_turn_feed_out_on_one_circle(direction: str) -> None:
    feed_in, turn, feed_out = _circle(direction=direction, feed_in_deg=180, feed_out_deg=90)
    r_m = R_MM * 1e-3
    assert [s.length_m for s in (feed_in, turn, feed_out)] == pytest.approx(
        [math.pi * r_m, 2 * math.pi * r_m, 0.5 * math.pi * r_m])
    np.testing.assert_array_equal(feed_in.start_m, [0.0, 0.0])  # the program still starts at start_mm
    np.testing.assert_allclose(turn.start_m, [0.0, 2 * r_m], atol=1e-15)  # 180° on: the top of the circle
    np.testing.assert_array_equal(turn.end_m, turn.start_m)
    side = 1.0 if direction == "ccw" else -1.0  # ccw from the top turns towards -x
    np.testing.assert_allclose(feed_out.end_m, [-side * r_m, r_m], atol=1e-15)
    for s in (feed_in, turn, feed_out):
        np.testing.assert_allclose(s.center_m, [0.0, r_m], atol=1e-15)
        assert s.clockwise == (direction == "cw")


def test_a_feed_arc_out_of_range_is_refused() -> None:
    with pytest.raises(ConfigError, match="feed_in_deg"):
        _circle(feed_in_deg=400)
    with pytest.raises(ConfigError, match="feed_out_deg"):
        _circle(feed_out_deg=-1)
