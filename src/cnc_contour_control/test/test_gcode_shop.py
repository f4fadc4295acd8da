"""G-code that shops write: R arcs, program end, dwell, work offsets, G61/G64, arc centre modes, refusals.

Expected centres and directions are worked out by hand in the comments.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError, ProgramError
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.gcode import parse_gcode
from cnc_contour_control.motion.geometry import ArcSegment
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.program import load_program
from cnc_contour_control.motion.program_goal import ProgramGoal

XY = ("x", "y")


def _arc(text: str, axes: tuple[str, ...] = XY) -> ArcSegment:
    arc = parse_gcode(text, axes=axes).segments[-1]
    assert isinstance(arc, ArcSegment)
    return arc


# ----------------------------------------------------------------------------------------------- R arcs
@pytest.mark.parametrize("text, center_mm, sweep_rad", [
    # chord (0,0)->(10,10), midpoint (5,5), rise sqrt(100 - 50) along the left normal (-1,1)/sqrt2
    ("G3 X10 Y10 R10 F100", [0, 10], math.pi / 2),        # short ccw: centre left of the chord
    ("G2 X10 Y10 R10 F100", [10, 0], math.pi / 2),        # short cw: right
    ("G3 X10 Y10 R-10 F100", [10, 0], 3 * math.pi / 2),   # long ccw: right
    ("G2 X10 Y10 R-10 F100", [0, 10], 3 * math.pi / 2),   # long cw: left
    ("G2 X10 R4.9995 F100", [5, 0], math.pi),             # within R_TOLERANCE_MM of half the chord: half circle
    ("G20 G3 X1 Y1 R1 F10", [0, 25.4], math.pi / 2),      # R in inches
])
def test_r_arcs_take_the_short_or_the_long_way(text: str, center_mm: list, sweep_rad: float) -> None:
    arc = _arc(text)
    assert_allclose(arc.center_m, np.array(center_mm) * 1e-3, atol=1e-12)
    assert arc.sweep_rad == pytest.approx(sweep_rad)


def test_r_arc_in_g18_turns_as_seen_from_plus_y() -> None:
    """G18 plane (Z, X): from the origin to X10 Z10, short ccw; centre left of the chord in (z, x): z 0, x 10."""
    arc = _arc("G18 G3 X10 Z10 R10 F100", ("x", "y", "z"))
    assert_allclose(arc.center_m[[0, 2]], [0.01, 0.0], atol=1e-12)
    assert_allclose(arc.tangent(0.0), [0.0, 0.0, 1.0], atol=1e-12)  # at the bottom of the circle, moving +Z


@pytest.mark.parametrize("text, message", [
    ("G1 F100\nG2 X10 R4", r"line 2: R4: radius 4 mm is smaller than half the chord, 5 mm"),
    ("G1 F100\nG20\nG2 X1 R0.4", r"line 3: R0.4: radius 10.16 mm is smaller than half the chord, 12.7 mm"),
    ("G2 X10 R5 I5 F100", r"line 1: R5 and I on one line \(give R or I/J/K\)"),
    ("G0 X5\nG2 R5 F100", r"line 2: R5: an R arc needs R != 0 and an end other than its start"),
    ("G2 X10 R0 F100", r"line 1: R0: an R arc needs R != 0"),
    ("G1 X1 F100\nX2 R3", r"line 2: R3 without G2/G3"),
])
def test_bad_r_arcs_are_refused_naming_the_line_and_the_values(text: str, message: str) -> None:
    with pytest.raises(ProgramError, match=message):
        parse_gcode(text, axes=XY)


# ----------------------------------------------------------------------------------------------- M2/M30
@pytest.mark.parametrize("end", ["M30", "M2", "M02"])
def test_nothing_runs_after_the_program_end(end: str) -> None:
    with pytest.raises(ProgramError, match=r"line 4: X5 after the program's end \(M2/M30 on line 3\)"):
        parse_gcode(f"G1 X1 F100\nX2\n{end}\nX5", axes=XY)


def test_comments_and_percent_after_the_end_are_fine_and_the_end_line_moves() -> None:
    program = parse_gcode("G1 X1 F100\nX2 M30\n(done)\n\n%", axes=XY)
    assert_allclose(program.end_m, [0.002, 0.0])


# ----------------------------------------------------------------------------------------------- G4 dwell
def test_dwells_are_carried_at_their_junction_with_their_line() -> None:
    program = parse_gcode("G4 P0.5\nG1 X10 F600\nG4 P1\nY10\nG4 P0.25", axes=XY)
    assert [(d.before_segment, d.duration_s, d.source_line) for d in program.dwells] == [
        (0, 0.5, 1), (1, 1.0, 3), (2, 0.25, 5)]
    assert_allclose(program.junction_dwell_s, [0.5, 1.0, 0.25])


def test_the_interpolator_holds_still_for_the_dwell() -> None:
    limits = AxisLimits((0.05, 0.05), (0.5, 0.5))
    plain = Interpolator(parse_gcode("G1 X10 F600\nY10", axes=XY), limits)
    dwelt = Interpolator(parse_gcode("G1 X10 F600\nG4 P0.75\nY10\nG4 P0.5", axes=XY), limits)
    assert dwelt.duration_s == pytest.approx(plain.duration_s + 1.25)  # a 90° corner already stops
    corner_s = plain.duration_s / 2  # symmetric legs: the corner is reached halfway
    for t_s in (corner_s + 0.01, corner_s + 0.4, corner_s + 0.74):
        sample = dwelt.sample(t_s)
        assert_allclose(sample.position_m, [0.01, 0.0], atol=1e-15)
        assert_allclose(sample.velocity_m_s, [0.0, 0.0]) and sample.segment_index == 1
    moving = dwelt.sample(corner_s + 0.76)
    assert moving.velocity_m_s[1] > 0.0
    ending = dwelt.sample(dwelt.duration_s - 0.4)
    assert_allclose(ending.position_m, [0.01, 0.01], atol=1e-15) and not ending.done


def test_a_dwell_stops_a_tangent_junction() -> None:
    limits = AxisLimits((0.05, 0.05), (0.5, 0.5))
    interpolator = Interpolator(parse_gcode("G1 X10 F600\nG4 P0.1\nX20", axes=XY), limits)
    assert interpolator.junction_speeds_m_s[1] == 0.0


@pytest.mark.parametrize("text, message", [
    ("G4", r"line 1: G4 without P \(the dwell time, s\)"),
    ("G4 P-1", r"line 1: P-1: the dwell time P must be in \[0, 3600\] s, got -1"),
    ("G4 P3601", r"line 1: P3601: the dwell time P must be in \[0, 3600\] s, got 3601"),
    ("G4 P1e9", r"line 1: G4 with E9; G4 takes only P"),
    ("G1 F100\nG4 P1 X3", r"line 2: G4 with X3; G4 takes only P"),
    ("G4 P1 Z5", r"line 1: G4 with Z5; G4 takes only P"),
    ("G4 P1 F100", r"line 1: G4 with F100; G4 takes only P"),
    ("G1 G4 P1", r"line 1: G4 with G1; G4 takes only P"),
    ("G1 X1 F100 P2", r"line 1: P2 without G4 or G64"),
    ("G4 G64 P1", r"line 1: P1 with both G4 and G64"),
])
def test_bad_dwells_are_refused(text: str, message: str) -> None:
    with pytest.raises(ProgramError, match=message):
        parse_gcode(text, axes=XY)


# ----------------------------------------------------------------------------------------------- work offsets
OFFSETS = {"G54": [1, 2], "G55": [100, 200]}


def test_work_offsets_move_absolute_words_only() -> None:
    program = parse_gcode("G1 X0 Y0 F100\nG55 X1\nG91 Y1\nG90 G54 X0", axes=XY, work_offsets_mm=OFFSETS)
    ends = [segment.end_m * 1e3 for segment in program.segments]
    assert_allclose(ends, [[1, 2], [101, 2], [101, 3], [1, 3]], atol=1e-9)  # Y keeps its machine position on G55


def test_arc_centres_in_a_work_offset() -> None:
    """G91.1: I/J from the start whatever the offset; G90.1: I/J in the work system."""
    program = parse_gcode("G55 G0 X0 Y0\nG3 X20 I10 F100\nG90.1 G3 X0 I10 J0\nG91.1 G3 X20 I10",
                          axes=XY, work_offsets_mm=OFFSETS)
    centres = [segment.center_m * 1e3 for segment in program.segments[1:]]
    assert_allclose(centres, [[110, 200]] * 3, atol=1e-9)


def test_work_offsets_come_from_the_program_section() -> None:
    program = load_program({"gcode": "G56 G1 X1 Y1 F100", "axes": ["x", "y"], "work_offsets_mm": {"G56": [5, 5]}})
    assert_allclose(program.end_m, [0.006, 0.006])


@pytest.mark.parametrize("offsets, message", [
    ({"G60": [0, 0]}, r"work_offsets_mm has unknown work offset 'G60'; valid: \['G54', .*'G59'\]"),
    ({"G54": [0, 0, 0]}, r"work_offsets_mm.G54 must be 2 finite numbers \(one per axis\), got \[0, 0, 0\]"),
    ({"G55": [0, float("nan")]}, r"work_offsets_mm.G55 must be 2 finite numbers"),
    ([1, 2], r"work_offsets_mm must be a mapping"),
])
def test_bad_work_offsets_are_refused(offsets: object, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_gcode("G1 X1 F100", axes=XY, work_offsets_mm=offsets)  # type: ignore[arg-type]  # bad offsets on purpose


# ----------------------------------------------------------------------------------------------- G61 / G64
@pytest.mark.parametrize("text, tolerance_m", [
    ("G1 X1 F100", None),
    ("G61\nG1 X1 F100", 0.0),
    ("G64 P0.02\nG1 X1 F100\nG64 P0.02\nX2", 2e-5),
    ("G20 G64 P0.001\nG1 X1 F100", 2.54e-5),
    ("G61\nG64 P0.05\nG1 X1 F100", 5e-5),  # changes before the first move: the last one holds
])
def test_path_tolerance_is_carried_on_the_program(text: str, tolerance_m: float | None) -> None:
    program = parse_gcode(text, axes=XY)
    assert program.path_tolerance_m == (None if tolerance_m is None else pytest.approx(tolerance_m))


@pytest.mark.parametrize("text, message", [
    ("G64\nG1 X1 F100", r"line 1: G64 without P \(the path tolerance\); use G61 for exact stop"),
    ("G64 P0", r"line 1: P0: the path tolerance P must be > 0, got 0"),
    ("G1 X1 F100\nG64 P-0.01", r"line 2: P-0.01: the path tolerance P must be > 0, got -0.01"),
    ("G64 Pinf\nG1 X1 F100", r"line 1: cannot read 'Pinf'"),
    ("G64 P0.01\nG1 X1 F100\nG61", r"line 3: G61 changes the path tolerance set on line 1 \(0.01 mm\) to 0 mm"),
])
def test_bad_path_control_is_refused(text: str, message: str) -> None:
    with pytest.raises(ProgramError, match=message):
        parse_gcode(text, axes=XY)


@pytest.mark.parametrize("value", [-1e-6, math.nan, math.inf])
def test_a_tolerance_below_zero_or_not_finite_is_refused_by_the_program_and_a_goal(value: float) -> None:
    """The other ways in besides G64 P (the interpolator's path_tolerance_mm: test_blending.py)."""
    program = parse_gcode("G1 X1 F100", axes=XY)
    with pytest.raises(ProgramError, match=rf"path_tolerance_m must be finite and >= 0, got {value}"):
        dataclasses.replace(program, path_tolerance_m=value)
    with pytest.raises(ProgramError, match=rf"path_tolerance_mm must be finite and >= 0, got {value * 1e3}"):
        ProgramGoal(gcode="G1 X1 F100", path_tolerance_mm=value * 1e3).check_options()


# ----------------------------------------------------------------------------------------------- G90.1 / G91.1
def test_absolute_arc_centres_then_incremental_again() -> None:
    program = parse_gcode("G0 X10 Y0\nG90.1 G3 X0 Y10 I0 J0 F100\nG91.1 G3 X-10 Y0 I0 J-10", axes=XY)
    first, second = program.segments[1:]
    assert_allclose(first.center_m, [0.0, 0.0], atol=1e-15)
    assert_allclose(second.center_m, [0.0, 0.0], atol=1e-15)
    assert first.sweep_rad == pytest.approx(math.pi / 2) and second.sweep_rad == pytest.approx(math.pi / 2)


def test_absolute_arc_centres_need_both_plane_words() -> None:
    with pytest.raises(ProgramError, match=r"line 2: G90.1 \(absolute arc centre\) needs both I/J, got \['I'\]"):
        parse_gcode("G0 X10\nG90.1 G3 X-10 I0 F100", axes=XY)


# ----------------------------------------------------------------------------------------------- refusals
@pytest.mark.parametrize("text, message", [
    ("G93 G1 X1 F2", r"line 1: G93: G93 \(inverse-time feed\) is not supported: give F in mm/min under G94"),
    ("G1 X١٢ F100", r"line 1: non-ASCII character '١' \(U\+0661\)"),
    ("G1 X1 F１００", r"line 1: non-ASCII character '１' \(U\+FF11\)"),
    ("G1 X1 F100\nN20 G1 X1 Y1 F0", r"line 2 \(N20\): F0: F must be >= 0.01 mm/min"),
])
def test_refusals_name_the_line(text: str, message: str) -> None:
    with pytest.raises(ProgramError, match=message):
        parse_gcode(text, axes=XY)


def test_non_ascii_in_comments_is_fine() -> None:
    program = parse_gcode("(Ø10 Fräser, ١٢)\nG1 X12 F100 ; größer", axes=XY)
    assert_allclose(program.end_m, [0.012, 0.0])


def test_limit_errors_name_the_g_code_line() -> None:
    program = parse_gcode("%\nG1 X10 F600\n(fast)\nG1 Y10 F3000", axes=XY)
    assert [segment.source_line for segment in program.segments] == [2, 4]
    limits = AxisLimits((0.03, 0.03), (1.0, 1.0))  # 1800 mm/min
    message = r"line 4 \(segment 1\): feed_mm_min must be <= 1800 \(axis velocity limits along the segment\), got 3000"
    with pytest.raises(ProgramError, match=message):
        Interpolator(program, limits)


# ----------------------------------------------------------------------------------------------- planes
def test_scenario_plane_xz_ccw_turns_as_g18_g3() -> None:
    """Seen from +Y, Z points right and X up: from X10 around the origin, ccw first moves toward -Z."""
    gcode = parse_gcode("G0 X10\nG18 G3 X0 Z-10 I-10 F100").segments[1]
    for plane in ("xz", "zx", ["x", "z"]):
        explicit = load_program({"axes": ["x", "y", "z"], "start_mm": [10, 0, 0], "feed_mm_min": 100, "segments": [
            {"arc": {"to_mm": [0, 0, -10], "center_mm": [0, 0, 0], "direction": "ccw", "plane": plane}}]}).segments[0]
        assert isinstance(explicit, ArcSegment) and explicit.plane == gcode.plane == (2, 0)
        assert explicit.sweep_rad == pytest.approx(math.pi / 2) == gcode.sweep_rad
        for arc in (explicit, gcode):
            assert_allclose(arc.tangent(0.0), [0.0, 0.0, -1.0], atol=1e-12)
            assert_allclose(arc.point(arc.length_m / 2), [0.01 / math.sqrt(2), 0.0, -0.01 / math.sqrt(2)], atol=1e-15)


def test_scenario_plane_xy_and_yx_ccw_turn_as_g17_g3() -> None:
    """Seen from +Z: from X10 around the origin, ccw first moves toward +Y, in either spelling."""
    for plane in ("xy", "yx"):
        arc = load_program({"axes": ["x", "y"], "start_mm": [10, 0], "feed_mm_min": 100, "segments": [
            {"arc": {"to_mm": [0, 10], "center_mm": [0, 0], "direction": "ccw", "plane": plane}}]}).segments[0]
        assert_allclose(arc.tangent(0.0), [0.0, 1.0], atol=1e-12)
        assert arc.sweep_rad == pytest.approx(math.pi / 2)
