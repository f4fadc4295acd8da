"""Tier 1: G-code files as shops write them (8-bit comments), files that are none, and the reader under fuzzing."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_contour_control.core.errors import CncError, ConfigError, ProgramError
from cnc_contour_control.motion.gcode import parse_gcode
from cnc_contour_control.motion.gcode_file import decode_gcode, read_gcode_file
from cnc_contour_control.motion.program import load_program
from cnc_contour_control.motion.program_file import read_program_file
from cnc_contour_control.motion.program_goal import ProgramGoal, goal_program

XY = ("x", "y")
HOLD_M = np.zeros(2)
LATIN1_PART = "(Fräser Ø 6 mm)\nG1 X10 F600 (Zustellung ½ mm)\nY5\n".encode("latin-1")


def test_a_latin1_comment_is_read_as_written(tmp_path: Path) -> None:
    part = tmp_path / "part.ngc"
    part.write_bytes(LATIN1_PART)
    text = read_gcode_file(part)
    assert text.splitlines()[0] == "(Fräser Ø 6 mm)"
    program = parse_gcode(text, XY)
    assert [s.source_line for s in program.segments] == [2, 3]
    assert read_program_file(part, XY).total_length_m == pytest.approx(0.015)
    assert load_program({"gcode_file": str(part), "axes": list(XY)}).total_length_m == pytest.approx(0.015)


def test_a_latin1_goal_file_is_planned(tmp_path: Path) -> None:
    part = tmp_path / "part.ngc"
    part.write_bytes(LATIN1_PART)
    program = goal_program(ProgramGoal(program_file=str(part)), XY, HOLD_M, 1e-6)
    assert program.name == "part" and program.total_length_m == pytest.approx(0.015)


def test_non_ascii_outside_a_comment_names_its_line(tmp_path: Path) -> None:
    part = tmp_path / "part.ngc"
    part.write_bytes("G1 X10 F600\nG1 Y5 Ä\n".encode("latin-1"))
    with pytest.raises(ProgramError, match=r"line 2: non-ASCII character 'Ä' \(U\+00C4\)"):
        parse_gcode(read_gcode_file(part), XY)


@pytest.mark.parametrize("make, message", [
    (lambda d: d, r"is a directory, not a file"),
    (lambda d: d / "none.ngc", r"does not exist"),
    (lambda d: (d / "bin.ngc", (d / "bin.ngc").write_bytes(b"G1 X1\0\xff"))[0],
     r"not a text file \(NUL byte at offset 5\)"),
])
def test_what_is_no_gcode_file_is_refused_with_the_reason(tmp_path: Path, make: object, message: str) -> None:
    path = make(tmp_path)  # type: ignore[operator]  # the parametrised lambdas take the folder
    with pytest.raises(ProgramError, match=message):
        read_gcode_file(path)
    with pytest.raises(CncError, match=message):
        read_program_file(path, XY)
    with pytest.raises(ProgramError, match=message):
        goal_program(ProgramGoal(program_file=str(path)), XY, HOLD_M, 1e-6)
    with pytest.raises(ConfigError, match=message):
        load_program({"gcode_file": str(path), "axes": list(XY)})


def test_a_directory_named_like_gcode_is_a_directory(tmp_path: Path) -> None:
    folder = tmp_path / "part.ngc"
    folder.mkdir()
    with pytest.raises(ProgramError, match=r"'.*part.ngc' is a directory"):
        goal_program(ProgramGoal(program_file=str(folder)), XY, HOLD_M, 1e-6)


def test_a_file_over_the_limit_is_refused(tmp_path: Path) -> None:
    part = tmp_path / "big.ngc"
    part.write_bytes(b"G1 X1 F100\n" * 20)
    with pytest.raises(ProgramError, match=r"is 220 bytes; the limit is 100 bytes"):
        read_gcode_file(part, limit_bytes=100)


# ----------------------------------------------------------------------------------------------- properties
#: Letters the reader knows on a line of an X/Y program: axes, offsets, and G M N F P R S T.
KNOWN_LETTERS = set("XYIJKGMNFPRST")
WORD_LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
NUMBERS = st.one_of(st.integers(-400, 400).map(str), st.sampled_from(["0", "1", "2", "3", "4", "17", "90.1", "64",
                                                                    "1.5", ".5", "-0.25", "1e9", "30"]))
TOKEN = st.one_of(
    st.tuples(st.sampled_from(WORD_LETTERS), NUMBERS).map("".join),
    st.sampled_from(["(comment)", "(Fräser Ø 6)", ";", "%", "(", ")", " ", "#1", "=", "[", "]", "\t", "O100"]))
FUZZ = settings(max_examples=150, deadline=None)


@FUZZ
@given(st.binary(max_size=300))
def test_random_bytes_raise_nothing_but_the_suites_errors(data: bytes) -> None:
    try:
        parse_gcode(decode_gcode(data), XY, feed_mm_min=100.0)
    except CncError:
        pass


@FUZZ
@given(st.lists(TOKEN, min_size=1, max_size=6).map(" ".join))
def test_token_soup_raises_only_suite_errors_and_never_passes_an_unknown_word(line: str) -> None:
    try:  # after a move, so a line that reads is never hidden behind "no motion"
        parse_gcode(f"G1 X0.5 F100\n{line}", XY)
    except CncError:
        return
    code = re.sub(r"\([^()]*\)", " ", line).split(";", 1)[0]
    letters = {m.group(1).upper() for m in re.finditer(r"([A-Za-z])\s*[-+]?[0-9.]", code)}
    assert letters <= KNOWN_LETTERS, f"accepted a line with an unknown word: {line!r}"
