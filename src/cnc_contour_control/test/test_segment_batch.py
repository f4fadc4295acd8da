"""Segments built over arrays (segment_batch) equal the ones their constructors build, field by field."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment
from cnc_contour_control.motion.segment_batch import arc_segments, line_segments

ARC_FIELDS = ("start_m", "end_m", "center_m", "clockwise", "plane", "feed_m_s", "source_line", "radius_m",
              "sweep_rad", "start_angle_rad", "length_m", "rise_m")
LINE_FIELDS = ("start_m", "end_m", "feed_m_s", "source_line", "length_m", "unit_vector")


def assert_same_fields(built: object, reference: object, names: tuple[str, ...]) -> None:
    assert type(built) is type(reference)
    for name in names:
        mine, theirs = getattr(built, name), getattr(reference, name)
        if isinstance(theirs, np.ndarray):
            assert_allclose(mine, theirs, rtol=0.0, atol=1e-12, err_msg=name)
            assert not mine.flags.writeable
        elif isinstance(theirs, float):
            assert mine == pytest.approx(theirs, rel=1e-12, abs=1e-15), name
        else:
            assert mine == theirs and type(mine) is type(theirs), name


def random_arcs(rng: np.random.Generator, n: int, n_axes: int = 3) -> dict:
    """Arcs in random planes: partial and full circles, helices (rise on the third axis), both directions."""
    choices = np.array([(0, 1), (0, 2), (1, 2), (2, 0)] if n_axes > 2 else [(0, 1), (1, 0)])
    planes = choices[rng.integers(0, len(choices), n)]
    center = rng.uniform(-0.05, 0.05, (n, n_axes))
    radius, start_angle = rng.uniform(1e-4, 0.02, n), rng.uniform(-math.pi, math.pi, n)
    clockwise = rng.random(n) < 0.5
    sweep = np.where(rng.random(n) < 0.1, 2 * math.pi, rng.uniform(1e-3, 2 * math.pi, n))
    end_angle = start_angle + np.where(clockwise, -sweep, sweep)
    start, end = center.copy(), center.copy() + rng.uniform(-0.01, 0.01, (n, n_axes)) * (rng.random((n, 1)) < 0.3)
    rows = np.arange(n)
    for points, angle in ((start, start_angle), (end, end_angle)):
        points[rows, planes[:, 0]] = center[rows, planes[:, 0]] + radius * np.cos(angle)
        points[rows, planes[:, 1]] = center[rows, planes[:, 1]] + radius * np.sin(angle)
    return {"start_m": start, "end_m": end, "center_m": center, "clockwise": clockwise, "plane": planes,
            "feed_m_s": rng.uniform(1e-3, 0.05, n), "source_line": [int(k) if k % 3 else None for k in range(n)]}


@pytest.mark.parametrize("seed", range(4))
def test_arcs_equal_the_constructor(seed: int) -> None:
    arcs = random_arcs(np.random.default_rng(seed), 200)
    built = arc_segments(**arcs)
    for i, arc in enumerate(built):
        reference = ArcSegment(arcs["start_m"][i], arcs["end_m"][i], arcs["center_m"][i], bool(arcs["clockwise"][i]),
                               tuple(int(a) for a in arcs["plane"][i]), float(arcs["feed_m_s"][i]),
                               arcs["source_line"][i])
        assert_same_fields(arc, reference, ARC_FIELDS)
        s = np.linspace(0.0, reference.length_m, 7)
        assert_allclose(arc.point(s), reference.point(s), atol=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_lines_equal_the_constructor(seed: int) -> None:
    rng = np.random.default_rng(seed)
    start = rng.uniform(-0.1, 0.1, (300, 3))
    end = start + rng.uniform(-0.01, 0.01, (300, 3)) * 10.0 ** rng.uniform(-6, 0, (300, 1))
    feed, lines = rng.uniform(1e-3, 0.05, 300), list(range(300))
    for i, line in enumerate(line_segments(start, end, feed, lines)):
        assert_same_fields(line, LineSegment(start[i], end[i], float(feed[i]), i), LINE_FIELDS)


def test_a_bad_row_raises_the_constructors_error() -> None:
    start, end = np.zeros((3, 2)), np.array([[1e-3, 0.0], [0.0, 0.0], [2e-3, 0.0]])
    with pytest.raises(ProgramError, match=r"line length_m must be >= 1e-09, got 0\.0"):
        line_segments(start, end, np.full(3, 0.01), [1, 2, 3])
    arcs = random_arcs(np.random.default_rng(9), 5, n_axes=2)
    arcs["end_m"][3] += [1e-4, 0.0]
    with pytest.raises(ProgramError, match="arc end_m is not on the circle"):
        arc_segments(**arcs)
    arcs = random_arcs(np.random.default_rng(9), 5, n_axes=2)
    arcs["feed_m_s"][1] = -1.0
    with pytest.raises(ProgramError, match="feed_m_s must be > 0, got -1"):
        arc_segments(**arcs)
