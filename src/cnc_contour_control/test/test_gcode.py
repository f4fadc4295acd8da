"""The G-code subset reader: moves, modes, comments, and errors naming the line and word."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError, ProgramError
from cnc_contour_control.motion.gcode import parse_gcode
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment

PART = """%
(a test part)
N10 G21 G90 G17 ; metric, absolute, XY
N20 G0 X0 Y0 Z0
N30 G1 X10 F600
N40 G3 X20 Y10 J10 (quarter ccw)
N50 g2 x30 y0 i10 j0
N60 G1 Y-5 F1200
M30
%
"""


def test_a_part_reads_into_segments() -> None:
    program = parse_gcode(PART, name="part")
    kinds = [type(segment).__name__ for segment in program.segments]
    assert kinds == ["LineSegment", "ArcSegment", "ArcSegment", "LineSegment"]
    line, ccw, cw, last = program.segments
    assert_allclose(line.end_m, [0.01, 0.0, 0.0])
    assert not ccw.clockwise and cw.clockwise
    assert_allclose(ccw.center_m, [0.01, 0.01, 0.0])
    assert_allclose(cw.center_m, [0.03, 0.01, 0.0])
    assert_allclose([s.feed_m_s for s in program.segments], [0.01, 0.01, 0.01, 0.02])
    assert_allclose(program.end_m, [0.03, -0.005, 0.0])
    assert program.name == "part" and program.axis_names == ("x", "y", "z")


def test_rapid_moves_use_the_rapid_feed_parameter() -> None:
    program = parse_gcode("G0 X5 Y5\nG1 X6 F100", rapid_feed_mm_min=3000.0)
    assert_allclose([s.feed_m_s for s in program.segments], [0.05, 100 / 60000])


@pytest.mark.parametrize("text, end_mm", [
    ("G91 G1 X5 F100\nX5 Y5\nY-10", [10.0, -5.0, 0.0]),
    ("G20 G1 X1 Y2 F10", [25.4, 50.8, 0.0]),
    ("G1 X5 F100\nG91\nX1\nG90\nX2", [2.0, 0.0, 0.0]),
])
def test_distance_and_unit_modes(text: str, end_mm: list) -> None:
    assert_allclose(parse_gcode(text).end_m, np.array(end_mm) * 1e-3)


def test_inch_feed_is_converted() -> None:
    program = parse_gcode("G20 G1 X1 F10")
    assert_allclose(program.segments[0].feed_m_s, 254e-3 / 60)


@pytest.mark.parametrize("text, plane, clockwise, center_mm", [
    ("G17 G2 X10 Y10 I10 F100", (0, 1), True, [10, 0, 0]),
    ("G18 G2 X10 Z10 K10 F100", (2, 0), True, [0, 0, 10]),
    ("G19 G3 Y10 Z-10 J10 F100", (1, 2), False, [0, 10, 0]),
])
def test_arc_planes(text: str, plane: tuple, clockwise: bool, center_mm: list) -> None:
    (arc,) = parse_gcode(text).segments
    assert isinstance(arc, ArcSegment)
    assert arc.plane == plane and arc.clockwise is clockwise
    assert_allclose(arc.center_m, np.array(center_mm) * 1e-3)
    assert arc.sweep_rad == pytest.approx(math.pi / 2)


def test_g18_clockwise_is_seen_from_plus_y() -> None:
    """Seen from +Y, Z points right and X up: G2 from +X turns toward +Z."""
    (arc,) = parse_gcode("G0 X10\nG18 G2 X0 Z10 I-10 F100").segments[1:]
    assert arc.sweep_rad == pytest.approx(math.pi / 2)
    assert_allclose(arc.tangent(0.0), [0.0, 0.0, 1.0], atol=1e-12)


def test_full_circle_and_helix() -> None:
    program = parse_gcode("G0 X10\nG2 I-10 F100\nG3 I-10 Z-2")
    circle, helix = program.segments[1:]
    assert circle.sweep_rad == pytest.approx(2 * math.pi) and circle.is_planar
    assert helix.sweep_rad == pytest.approx(2 * math.pi) and not helix.is_planar
    assert_allclose(helix.length_m, math.hypot(2 * math.pi * 0.01, 0.002))


def test_zero_length_moves_and_mode_only_lines_are_skipped() -> None:
    program = parse_gcode("G1 X0 Y0 F100\nG1 X1\nG1 X1\nG2\nG1\nS1000 M3 T1\nX2")
    assert len(program.segments) == 2
    assert all(isinstance(s, LineSegment) for s in program.segments)


def test_two_axis_programs_and_start() -> None:
    program = parse_gcode("G1 X1 Y1 F60", axes=("x", "y"), start_mm=(1.0, 0.0))
    assert_allclose(program.start_m, [0.001, 0.0])
    assert program.segments[0].length_m == pytest.approx(0.001)


@pytest.mark.parametrize("text, message", [
    ("G1 X10", r"line 1: G1 without a feed \(F\)"),
    ("G1 X1 F100\n\n(comment)\nG2 X2 Y1", r"line 4: G2 without I/J/K"),
    ("G1 F100\nG3 X10", r"line 2: G3 without I/J/K"),
    ("G1 X1 R5 F100", "line 1: R5 without G2/G3"),
    ("G59.1 G1 X1 F100", "line 1: unsupported word G59.1"),
    ("G92 X0", "line 1: unsupported word G92"),
    ("G1 X1 F100 G2", "line 1: G1 and G2 on one line"),
    ("X1", "line 1: X1 without a motion mode"),
    ("G1 X1 F0", r"line 1: F0: F must be >= 0.01 mm/min \(0.01 in this program's units\), got 0"),
    ("G1 X1 F0.0000001", r"line 1: F0.0000001: F must be >= 0.01 mm/min \(0.01 in this .*got 1e-07"),
    ("G1 X1 I3 F100", "line 1: I3 without G2/G3"),
    ("G2 X1 K4 F100", r"line 1: K4 is not allowed in plane G17 \(use I/J\)"),
    ("G1 X1 X2 F100", "line 1: word X twice"),
    ("G1 X1 F100 (unclosed", "line 1: unbalanced comment"),
    ("G1 X1 F100 #1=2", "line 1: cannot read '#1=2'"),
    ("G1 X1 Y1 F100\nG2 X3 Y1 I2 J0", r"line 2: arc end_m is not on the circle"),
    ("G1 Z1 F100", "line 1: unsupported word Z1 \\(program axes \\['X', 'Y'\\]"),
    ("G18 G2 X1 K1 F100", r"line 1: G2 in plane G18 needs axes \['Z', 'X'\]"),
    ("(nothing)\n%", "gcode: the G-code has no motion"),
])
def test_errors_name_the_line_and_the_word(text: str, message: str) -> None:
    axes = ("x", "y", "z") if "Z" not in text and "G18" not in text else ("x", "y")
    with pytest.raises(ProgramError, match=message):
        parse_gcode(text, axes=axes)


@pytest.mark.parametrize("kwargs, message", [
    ({"axes": ("x", "i")}, "axes must be distinct single letters"),
    ({"axes": ("x", "x")}, "axes must be distinct single letters"),
    ({"rapid_feed_mm_min": -1.0}, "rapid_feed_mm_min must be > 0, got -1.0"),
    ({"start_mm": (0.0,)}, "start_mm must be 3 finite numbers"),
])
def test_bad_options_are_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_gcode("G1 X1 F100", **kwargs)
