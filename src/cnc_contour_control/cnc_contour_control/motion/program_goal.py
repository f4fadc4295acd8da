"""A program sent at run time (the RunProgram action's goal) into a :class:`Program` (ROS-free).

A goal gives exactly one source (registry :data:`GOAL_SOURCES`):

``gcode``
    G-code text, read from where the machine stands: the position before the
    first move is the commanded (hold) position, so the program's first move
    is its approach, as on a CNC.
``program_file``
    a file on the interpolator's host: G-code (:data:`GCODE_SUFFIXES`, read as
    ``gcode``) or a YAML program or scenario (must start at the machine).
``segments``
    the contour as :class:`SegmentSpec` (the fields of ``PathSegment.msg``),
    which must start at the machine.

"Start at the machine": the program's start is within ``start_tolerance_m``
of the hold position, else :class:`~cnc_contour_control.core.errors.ProgramError`
names the distance (no move is inserted: a program that needs an approach
says so in G-code). ``feed_mm_min`` is the feed of moves that give none (G1/G2/G3
before the first F, segments with ``feed_m_s`` 0).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.core.units import m_to_mm, mm_min_to_m_s
from cnc_contour_control.motion.gcode import parse_gcode
from cnc_contour_control.motion.gcode_file import read_gcode_file
from cnc_contour_control.motion.geometry import ArcSegment, FloatArray, LineSegment, Program, Segment
from cnc_contour_control.motion.program_file import GCODE_SUFFIXES, read_program_file

#: ``PathSegment.kind`` values (LINE, ARC_CW, ARC_CCW) -> clockwise (None: a line).
SEGMENT_KINDS: dict[int, bool | None] = {0: None, 1: True, 2: False}


@dataclass(frozen=True)
class SegmentSpec:
    """One segment of a goal's path, as ``PathSegment.msg`` gives it (m, m/s; machine axes).

    ``kind`` is a key of :data:`SEGMENT_KINDS`; ``center_m`` is empty for lines;
    ``feed_m_s`` 0 takes the goal's ``feed_mm_min``.
    """

    kind: int
    start_m: tuple[float, ...]
    end_m: tuple[float, ...]
    center_m: tuple[float, ...] = ()
    plane_axes: tuple[int, int] = (0, 1)
    feed_m_s: float = 0.0


@dataclass(frozen=True)
class ProgramGoal:
    """A RunProgram goal: one source of ``gcode``, ``program_file``, ``segments``, and its options.

    Parameters
    ----------
    gcode : str
        G-code text ("" when another source is given).
    program_file : str
        Path of a program file on this host ("" when another source is given).
    segments : tuple of SegmentSpec
        The contour (empty when another source is given).
    program_name : str
        Name of the program ("": ``gcode``, the file's stem, ``segments``).
    feed_mm_min : float
        Feed of moves that give none, mm/min, >= 0 (0: none).
    path_tolerance_mm : float
        Corner blend tolerance unless the program sets one, mm, >= 0 (0: the node's).
    """

    gcode: str = ""
    program_file: str = ""
    segments: tuple[SegmentSpec, ...] = field(default=())
    program_name: str = ""
    feed_mm_min: float = 0.0
    path_tolerance_mm: float = 0.0

    def source(self) -> str:
        """The one source the goal gives; a ProgramError listing what it gives otherwise."""
        given = [name for name in GOAL_SOURCES if _given(self, name)]
        if len(given) != 1:
            raise ProgramError(f"a goal must give exactly one of {list(GOAL_SOURCES)}, got {given or 'none'}")
        return given[0]

    def check_options(self) -> None:
        """Refuse a negative or non-finite feed or tolerance, naming it."""
        for name in ("feed_mm_min", "path_tolerance_mm"):
            value = float(getattr(self, name))
            if not (np.isfinite(value) and value >= 0.0):
                raise ProgramError(f"{name} must be finite and >= 0, got {value}")


def _given(goal: ProgramGoal, name: str) -> bool:
    value = getattr(goal, name)
    return bool(value.strip()) if isinstance(value, str) else bool(value)


def _gcode(goal: ProgramGoal, axes: tuple[str, ...], hold_m: FloatArray) -> Program:
    return _parse(goal.gcode, goal.program_name or "gcode", goal, axes, hold_m)


def _parse(text: str, name: str, goal: ProgramGoal, axes: tuple[str, ...], hold_m: FloatArray) -> Program:
    feed = goal.feed_mm_min if goal.feed_mm_min > 0.0 else None
    return parse_gcode(text, axes, start_mm=[m_to_mm(float(v)) for v in hold_m], name=name, feed_mm_min=feed)


def _file(goal: ProgramGoal, axes: tuple[str, ...], hold_m: FloatArray) -> Program:
    path = Path(goal.program_file)
    if path.suffix.lower() in GCODE_SUFFIXES:
        return _parse(read_gcode_file(path), goal.program_name or path.stem, goal, axes, hold_m)
    program = read_program_file(path, axes)
    if goal.program_name:
        program = Program(goal.program_name, program.axis_names, program.segments, program.dwells,
                          program.path_tolerance_m)
    return program


def _segments(goal: ProgramGoal, axes: tuple[str, ...], hold_m: FloatArray) -> Program:
    default_m_s = mm_min_to_m_s(goal.feed_mm_min) if goal.feed_mm_min > 0.0 else 0.0
    segments = [spec_to_segment(i, spec, default_m_s) for i, spec in enumerate(goal.segments)]
    return Program(goal.program_name or "segments", axes, tuple(segments))


def spec_to_segment(index: int, spec: SegmentSpec, default_feed_m_s: float) -> Segment:
    """Segment ``index`` of a goal's path; its feed, or ``default_feed_m_s`` where it gives 0."""
    if spec.kind not in SEGMENT_KINDS:
        raise ProgramError(f"segment {index}: kind must be one of {sorted(SEGMENT_KINDS)} (LINE, ARC_CW, ARC_CCW), "
                           f"got {spec.kind}")
    feed_m_s = spec.feed_m_s if spec.feed_m_s != 0.0 else default_feed_m_s
    if feed_m_s == 0.0:
        raise ProgramError(f"segment {index}: feed_m_s is 0 and the goal gives no feed_mm_min")
    clockwise = SEGMENT_KINDS[spec.kind]
    try:
        if clockwise is None:
            return LineSegment(np.array(spec.start_m), np.array(spec.end_m), feed_m_s)
        return ArcSegment(np.array(spec.start_m), np.array(spec.end_m), np.array(spec.center_m), clockwise,
                          (int(spec.plane_axes[0]), int(spec.plane_axes[1])), feed_m_s)
    except ProgramError as err:
        raise ProgramError(f"segment {index}: {err}") from err


#: Goal source -> reader (goal, axes, hold position m) -> Program.
GOAL_SOURCES: dict[str, Callable[[ProgramGoal, tuple[str, ...], FloatArray], Program]] = {
    "gcode": _gcode, "program_file": _file, "segments": _segments}


def goal_program(goal: ProgramGoal, axes: Sequence[str], hold_m: FloatArray, start_tolerance_m: float) -> Program:
    """The goal's program over ``axes``, starting at the hold position ``hold_m`` (m, shape ``(n_axes,)``).

    Raises
    ------
    ProgramError
        On a malformed program (G-code errors name the line), a program over
        other axes, or one starting farther than ``start_tolerance_m`` from ``hold_m``.
    """
    axes = tuple(axes)
    goal.check_options()
    program = GOAL_SOURCES[goal.source()](goal, axes, np.asarray(hold_m, dtype=float))
    if tuple(program.axis_names) != axes:
        raise ProgramError(f"program axes {list(program.axis_names)} differ from the interpolator's {list(axes)}")
    gap_m = float(np.linalg.norm(program.start_m - np.asarray(hold_m, dtype=float)))
    if gap_m > start_tolerance_m:
        raise ProgramError(f"program {program.name!r} starts at {np.round(program.start_m, 9).tolist()} m, "
                           f"{gap_m:.6g} m from the machine at {np.round(hold_m, 9).tolist()} m; it must start "
                           f"within start_tolerance_mm = {m_to_mm(start_tolerance_m):g} mm (or be G-code, whose "
                           f"first move is the approach)")
    return program
