"""Programs from a scenario's program: section: shapes, explicit segments, G-code, bad input."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError, ProgramError
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment
from cnc_contour_control.motion.program import SHAPES, SOURCES, load_program


def test_default_circle_is_paper000s_circular_test() -> None:
    program = load_program({"shape": "circle", "radius_mm": 20, "feed_mm_min": 400})
    (arc,) = program.segments
    assert isinstance(arc, ArcSegment) and not arc.clockwise
    assert_allclose(arc.center_m, [0.0, 0.02], atol=1e-15)
    assert_allclose(arc.start_m, [0.0, 0.0])
    assert_allclose(program.total_length_m, 2 * math.pi * 0.02)
    assert_allclose(arc.feed_m_s, 0.4 / 60)
    assert program.axis_names == ("x", "y") and program.name == "program"


@pytest.mark.parametrize("direction, start_angle_deg, center_mm, clockwise", [
    ("cw", -90.0, [0.0, 10.0], True),
    ("ccw", 0.0, [-10.0, 0.0], False),
    ("ccw", 180.0, [10.0, 0.0], False),
])
def test_circle_options(direction: str, start_angle_deg: float, center_mm: list, clockwise: bool) -> None:
    program = load_program({"shape": "circle", "radius_mm": 10, "feed_mm_min": 1300, "direction": direction,
                            "start_angle_deg": start_angle_deg, "name": "c"})
    arc = program.segments[0]
    assert arc.clockwise is clockwise and program.name == "c"
    assert_allclose(arc.center_m, np.array(center_mm) * 1e-3, atol=1e-15)
    assert arc.sweep_rad == pytest.approx(2 * math.pi)


def test_line_shape_at_five_degrees() -> None:
    program = load_program({"shape": "line", "angle_deg": 5, "length_mm": 50, "feed_mm_min": 900})
    (line,) = program.segments
    assert_allclose(line.end_m, 0.05 * np.array([math.cos(math.radians(5)), math.sin(math.radians(5))]))
    assert_allclose(line.feed_m_s, 0.015)


def test_corner_shape_in_three_axes_from_a_start() -> None:
    program = load_program({"shape": "corner", "leg_mm": 20, "feed_mm_min": 300, "axes": ["x", "y", "z"],
                            "start_mm": [1, 2, 3]})
    first, second = program.segments
    assert_allclose(first.end_m, [0.021, 0.002, 0.003], atol=1e-15)
    assert_allclose(second.end_m, [0.021, 0.022, 0.003], atol=1e-15)
    assert_allclose(np.dot(first.unit_vector, second.unit_vector), 0.0, atol=1e-15)


def test_explicit_segments_with_default_feed_and_planes() -> None:
    program = load_program({
        "axes": ["x", "y", "z"], "start_mm": [0, 0, 0], "feed_mm_min": 600,
        "segments": [
            {"line": {"to_mm": [10, 0, 0]}},
            {"arc": {"to_mm": [20, 10, 0], "center_mm": [10, 10, 0], "direction": "ccw", "plane": "xy"}},
            {"arc": {"to_mm": [20, 10, 10], "center_mm": [20, 10, 5], "direction": "cw", "plane": ["z", "x"],
                     "feed_mm_min": 300}},
        ]})
    line, arc_xy, arc_zx = program.segments
    assert isinstance(line, LineSegment) and line.feed_m_s == pytest.approx(0.01)
    assert arc_xy.plane == (0, 1) and arc_xy.sweep_rad == pytest.approx(math.pi / 2)
    assert arc_zx.plane == (2, 0) and arc_zx.feed_m_s == pytest.approx(0.005)
    assert_allclose(program.total_length_m, 0.01 + 0.01 * math.pi / 2 + 0.005 * math.pi)


def test_gcode_text_and_file(tmp_path: Path) -> None:
    text = "G21 G90\nG1 X10 Y0 F600\nG3 X20 Y10 J10\n"
    (tmp_path / "part.ngc").write_text(text, encoding="utf-8")
    inline = load_program({"gcode": text, "axes": ["x", "y"]})
    from_file = load_program({"gcode_file": "part.ngc", "axes": ["x", "y"]}, name="part", base_dir=tmp_path)
    assert from_file.name == "part" and len(from_file.segments) == 2
    assert_allclose(inline.total_length_m, from_file.total_length_m)
    assert_allclose(from_file.end_m, [0.02, 0.01])


def test_registries_list_the_forms() -> None:
    assert sorted(SHAPES) == ["circle", "corner", "line"]
    assert sorted(SOURCES) == ["gcode", "gcode_file", "segments", "shape"]


@pytest.mark.parametrize("mapping, message", [
    ({"shape": "circle", "radius_mm": -3, "feed_mm_min": 400}, "program.radius_mm must be > 0, got -3"),
    ({"shape": "circle", "radius_mm": 20, "feed_mm_min": 0}, "program.feed_mm_min must be > 0, got 0"),
    ({"shape": "line", "length_mm": 0, "feed_mm_min": 400}, "program.length_mm must be > 0, got 0"),
    ({"shape": "corner", "leg_mm": -1, "feed_mm_min": 400}, "program.leg_mm must be > 0, got -1"),
    ({"shape": "corner", "leg_mm": 5, "feed_mm_min": 400, "angle_deg": 270},
     r"program.angle_deg must be in \[-180.0, 180.0\], got 270"),
    ({"shape": "circle", "radius_mm": 20, "feed_mm_min": 400, "direction": "left"},
     r"program.direction must be one of \['ccw', 'cw'\], got 'left'"),
    ({"shape": "ellipse", "radius_mm": 20},
     r"program.shape must be one of \['circle', 'corner', 'line'\], got 'ellipse'"),
    ({"shape": "circle", "radius_mm": 20, "feed_mm_min": 400, "radius": 3},
     r"program.radius: unknown key; valid keys are "
     r"\['axes', 'direction', 'feed_in_deg', 'feed_mm_min', 'feed_out_deg'"),
    ({"shape": "circle", "feed_mm_min": 400}, "radius_mm"),
    ({"radius_mm": 20}, r"program needs exactly one of \['gcode', 'gcode_file', 'segments', 'shape'\]"),
    ({"shape": "circle", "gcode": "G1 X1"}, "program needs exactly one of"),
    ({"shape": "circle", "radius_mm": 20, "feed_mm_min": 400, "start_mm": [0, 0, 0]},
     "program.start_mm must have 2 entries"),
    ({"shape": "line", "length_mm": 5, "feed_mm_min": 400, "axes": ["x"]}, "at least two axes"),
    ({"segments": [{"line": {"to_mm": [1, 0]}}]}, r"segments\[0\].line.feed_mm_min is required"),
    ({"segments": [{"line": {"to_mm": [1, 0], "feed_mm_min": -5}}]},
     r"program.segments\[0\].line.feed_mm_min must be > 0, got -5"),
    ({"segments": [{"spline": {"to_mm": [1, 0]}}], "feed_mm_min": 100},
     r"program.segments\[0\].kind must be one of \['arc', 'line'\], got 'spline'"),
    ({"segments": [{"line": {"to": [1, 0]}}], "feed_mm_min": 100},
     r"program.segments\[0\].line.to: unknown key; valid keys are \['feed_mm_min', 'to_mm'\]"),
    ({"segments": [{"arc": {"to_mm": [1, 1], "center_mm": [0, 1], "direction": "cw", "plane": "xz"}}],
      "feed_mm_min": 100}, r"program.segments\[0\].arc.plane must name two of the axes \['x', 'y'\], got 'xz'"),
    ({"segments": [], "feed_mm_min": 100}, "program.segments must be a non-empty list"),
    ({"gcode_file": "/nonexistent/part.ngc"}, "program.gcode_file '/nonexistent/part.ngc' does not exist"),
    ({"gcode": "G1 X1 F100", "rapid_feed_mm_min": 0}, "rapid_feed_mm_min must be > 0, got 0"),
    # a boolean is no number (float(True) is 1.0: a 1 mm circle)
    ({"shape": "circle", "radius_mm": True, "feed_mm_min": 400}, "program.radius_mm must be a number, got True"),
    ({"shape": "circle", "radius_mm": 20, "feed_mm_min": False}, "program.feed_mm_min must be a number, got False"),
    ({"shape": "line", "length_mm": 5, "feed_mm_min": 400, "angle_deg": True},
     "program.angle_deg must be a number, got True"),
    ({"shape": "line", "length_mm": 5, "feed_mm_min": 400, "start_mm": [True, 0]},
     r"program.start_mm\[0\] must be a number, got True"),
    # the user's own quantity is refused by its name and bound, not a point or a duration computed from it
    ({"shape": "circle", "radius_mm": 1e300, "feed_mm_min": 400},
     r"program.radius_mm must be in \[0.001, 100000\] mm, got 1e\+300"),
    ({"shape": "circle", "radius_mm": 1e-300, "feed_mm_min": 400},
     r"program.radius_mm must be in \[0.001, 100000\] mm, got 1e-300"),
    ({"shape": "line", "length_mm": 2e5, "feed_mm_min": 400},
     r"program.length_mm must be in \[0.001, 100000\] mm, got 200000.0"),
    ({"shape": "corner", "leg_mm": 1e6, "feed_mm_min": 400},
     r"program.leg_mm must be in \[0.001, 100000\] mm, got 1000000.0"),
    ({"shape": "line", "length_mm": 10, "feed_mm_min": 400, "angle_deg": 1e300},
     r"program.angle_deg must be in \[-360.0, 360.0\], got 1e\+300"),
    ({"shape": "circle", "radius_mm": 20, "feed_mm_min": 400, "start_mm": [0, -1e300]},
     r"program.start_mm\[1\] must be in \[-100000, 100000\] mm, got -1e\+300"),
    ({"shape": "line", "length_mm": 10, "feed_mm_min": 0.0000001},
     "program.feed_mm_min must be >= 0.01 mm/min, got 1e-07"),
    ({"segments": [{"line": {"to_mm": [1, 0], "feed_mm_min": 0.001}}]},
     r"program.segments\[0\].line.feed_mm_min must be >= 0.01 mm/min, got 0.001"),
    ({"segments": [{"arc": {"to_mm": [0, 0], "center_mm": [0, 1e9], "direction": "cw"}}], "feed_mm_min": 100},
     r"program.segments\[0\].arc.center_mm\[1\] must be in \[-100000, 100000\] mm, got 1000000000.0"),
    ({"gcode": "G1 X1 F100", "rapid_feed_mm_min": 1e-9}, "program.rapid_feed_mm_min must be >= 0.01 mm/min"),
    ({"gcode": "G55 G1 X1 F100", "axes": ["x", "y"], "work_offsets_mm": {"G55": [True, 0]}},
     r"program.work_offsets_mm.G55\[0\] must be a number, got True"),
    ({"gcode": "G1 X1 F100", "axes": ["x", "y"], "start_mm": [0, 1e300]},
     r"program.start_mm\[1\] must be in \[-100000, 100000\] mm, got 1e\+300"),
])
def test_bad_program_sections_are_refused(mapping: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        load_program(mapping)


@pytest.mark.parametrize("segments, message", [
    ([{"line": {"to_mm": [10, 0]}}, {"arc": {"to_mm": [20.1, 10], "center_mm": [10, 10], "direction": "ccw"}}],
     r"program: segment 1: arc end_m is not on the circle: end radius 0.0101 m, start radius 0.01 m"),
    ([{"line": {"to_mm": [10, 0]}}, {"line": {"to_mm": [10, 0]}}],
     "program: segment 1: line length_m must be >="),
])
def test_bad_explicit_geometry_names_the_segment(segments: list, message: str) -> None:
    with pytest.raises(ProgramError, match=message):
        load_program({"segments": segments, "feed_mm_min": 100})
