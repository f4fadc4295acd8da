"""A G-code subset reader: the blocks of a program into a :class:`~cnc_contour_control.motion.geometry.Program`.

The subset, in short (``docs/gcode.md`` has it in full): G0/G1/G2/G3 moves
(arcs by I/J/K or R, full circles, helices), G4 P dwell (s), G17/G18/G19,
G20/G21, G54-G59 work offsets (given as the option ``work_offsets_mm``),
G61 exact stop and G64 P path tolerance (one per program, carried as
``Program.path_tolerance_m``), G90/G91, G90.1/G91.1 arc centre modes, G94;
G93 is refused. M2/M30 end the program: any word after them is refused.
F in mm/min (inch/min under G20); N, S, T and other M words are read and
ignored. Every error names the line of the text (1-based, and its N word),
and every segment carries its line (``source_line``), so a limit error of
the interpolator names the line too. Words are read by
:mod:`cnc_contour_control.motion.gcode_words`, arc centres found by
:mod:`cnc_contour_control.motion.gcode_arcs`.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from cnc_contour_control.core.config import require_positive
from cnc_contour_control.core.errors import ConfigError, ProgramError
from cnc_contour_control.core.units import mm_min_to_m_s, mm_to_m
from cnc_contour_control.motion.gcode_arcs import OFFSETS, PLANES, ArcFrame, center_from_offsets, center_from_radius
from cnc_contour_control.motion.gcode_words import G_CODES, PROGRAM_END_M, Block, read_block
from cnc_contour_control.motion.geometry import ArcSegment, Dwell, FloatArray, LineSegment, Program, Segment
from cnc_contour_control.motion.points import MIN_FEED_MM_MIN

__all__ = ["G_CODES", "OFFSETS", "PLANES", "WORK_OFFSETS", "parse_gcode"]

MM_PER_INCH = 25.4
#: Work offset names, in the option ``work_offsets_mm``, and the G code selecting each.
WORK_OFFSETS: dict[str, str] = {f"G{code}": code for code in ("54", "55", "56", "57", "58", "59")}
#: The modes at the start of a program, by modal group.
START_MODES: dict[str, str] = {"plane": "17", "units": "21", "work_offset": "54", "distance": "90",
                               "arc_distance": "91.1", "feed_mode": "94"}
_RESERVED = frozenset("GFIJKNMSTOPRLQDEH")
_IGNORED = frozenset("ST")
_MIN_MOVE_MM = 1.0e-9
#: Longest dwell G4 P may ask for, s (one hour: a longer stop is a program error, e.g. P in ms).
MAX_DWELL_S = 3600.0


@dataclass
class _State:
    """The modal state of the reader; positions in mm, machine coordinates."""

    position_mm: FloatArray
    axis_index: dict[str, int]
    rapid_feed_mm_min: float
    work_offsets_mm: dict[str, FloatArray]
    modes: dict[str, str] = field(default_factory=lambda: dict(START_MODES))
    motion: str | None = None
    feed_mm_min: float | None = None
    segments: list[Segment] = field(default_factory=list)
    dwells: list[Dwell] = field(default_factory=list)
    tolerance: tuple[float, int] | None = None  # (path tolerance mm, line)
    end_line: int | None = None

    @property
    def scale(self) -> float:
        """mm per program unit."""
        return MM_PER_INCH if self.modes["units"] == "20" else 1.0


def parse_gcode(text: str, axes: Sequence[str] = ("x", "y", "z"), *, rapid_feed_mm_min: float = 1000.0,
                start_mm: Sequence[float] | None = None, name: str = "gcode",
                work_offsets_mm: Mapping[str, Sequence[float]] | None = None,
                feed_mm_min: float | None = None) -> Program:
    """Read a G-code program.

    Parameters
    ----------
    text : str
        The program.
    axes : sequence of str
        Program axis names, single letters addressed by the words of the same
        letter (``"x"`` by X); I/J/K offset X/Y/Z.
    rapid_feed_mm_min : float
        Feed of G0 moves, mm/min, > 0.
    start_mm : sequence of float, optional
        Position before the first move, machine coordinates, mm, one per axis (default: origin).
    name : str
        Program name.
    work_offsets_mm : mapping, optional
        ``{"G54": [x, y, ...], ..., "G59": [...]}``: the machine position (mm,
        one per axis) of each work system's zero; absent ones are zero. G54
        is in force at the start.
    feed_mm_min : float, optional
        Feed in force before the first F word, mm/min, > 0 (default: none, a
        G1/G2/G3 before the first F is refused).

    Raises
    ------
    ProgramError
        On a malformed or unsupported line, naming the line and the word.
    ConfigError
        On a bad option.
    """
    axis_names = _check_axes(axes)
    state = _State(_start_mm(start_mm, len(axis_names)), {n.upper(): i for i, n in enumerate(axis_names)},
                   require_positive("rapid_feed_mm_min", rapid_feed_mm_min),
                   _work_offsets(work_offsets_mm, len(axis_names)))
    if feed_mm_min is not None:
        state.feed_mm_min = require_positive("feed_mm_min", feed_mm_min)
    for number, line in enumerate(text.splitlines(), start=1):
        block = read_block(line, number)
        if not block.empty:
            _execute(block, state)
    if not state.segments:
        raise ProgramError(f"{name}: the G-code has no motion")
    tolerance_m = None if state.tolerance is None else mm_to_m(state.tolerance[0])
    return Program(name, axis_names, tuple(state.segments), tuple(state.dwells), tolerance_m)


def _check_axes(axes: Sequence[str]) -> tuple[str, ...]:
    names = tuple(axes) if not isinstance(axes, str) else (axes,)
    bad = [n for n in names if not (isinstance(n, str) and len(n) == 1 and n.isascii() and n.isalpha())
           or n.upper() in _RESERVED]
    if not names or bad or len({n.upper() for n in names}) != len(names):
        raise ConfigError(
            f"axes must be distinct single letters other than {sorted(_RESERVED)}, got {list(names)}")
    return names


def _start_mm(start_mm: Sequence[float] | None, n_axes: int) -> FloatArray:
    start = np.zeros(n_axes) if start_mm is None else np.array(start_mm, dtype=float)
    if start.shape != (n_axes,) or not np.all(np.isfinite(start)):
        raise ConfigError(f"start_mm must be {n_axes} finite numbers, got {start_mm!r}")
    return start


def _work_offsets(given: Mapping[str, Sequence[float]] | None, n_axes: int) -> dict[str, FloatArray]:
    """Work offset by G code text (``"54"``), mm; refuses unknown names and wrong sizes."""
    offsets = {code: np.zeros(n_axes) for code in WORK_OFFSETS.values()}
    if given is None:
        return offsets
    if not isinstance(given, Mapping):
        raise ConfigError(f"work_offsets_mm must be a mapping of {sorted(WORK_OFFSETS)} to positions, got {given!r}")
    for key, value in given.items():
        if key not in WORK_OFFSETS:
            raise ConfigError(f"work_offsets_mm has unknown work offset {key!r}; valid: {sorted(WORK_OFFSETS)}")
        try:
            offset = np.array(value, dtype=float)
        except (TypeError, ValueError) as err:
            raise ConfigError(f"work_offsets_mm.{key} must be {n_axes} finite numbers, got {value!r}") from err
        if offset.shape != (n_axes,) or not np.all(np.isfinite(offset)):
            raise ConfigError(f"work_offsets_mm.{key} must be {n_axes} finite numbers (one per axis), got {value!r}")
        offsets[WORK_OFFSETS[key]] = offset
    return offsets


def _execute(block: Block, state: _State) -> None:
    """Apply ``block`` in the order of execution: modes and feed, dwell, motion, program end."""
    if state.end_line is not None:
        raise block.error(f"{block.first_word()} after the program's end (M2/M30 on line {state.end_line}); "
                          "nothing after it runs")
    _check_p_and_r(block, state)
    for group, code in block.g_codes.items():
        GROUP_ACTIONS[group](block, state, code)
    if "F" in block.words:
        feed, raw = block.words["F"]
        feed_mm_min = feed * state.scale
        if not feed > 0.0 or feed_mm_min < MIN_FEED_MM_MIN:
            raise block.error(f"{raw}: F must be >= {MIN_FEED_MM_MIN:g} mm/min "
                              f"({MIN_FEED_MM_MIN / state.scale:g} in this program's units), got {feed:g}")
        state.feed_mm_min = feed_mm_min
    if "non_modal" not in block.g_codes:
        _move(block, state)
    if PROGRAM_END_M.intersection(block.m_codes):
        state.end_line = block.number


def _check_p_and_r(block: Block, state: _State) -> None:
    """P belongs to G4 or G64, R to G2/G3."""
    takers = [f"G{code}" for code in block.g_codes.values() if code in ("4", "64")]
    if "P" in block.words and len(takers) != 1:
        taken = "without G4 or G64" if not takers else f"with both {' and '.join(takers)}"
        raise block.error(f"{block.words['P'][1]} {taken} (P is the dwell time or the path tolerance)")
    motion = block.g_codes.get("motion", state.motion)
    if "R" in block.words and motion not in ("2", "3"):
        raise block.error(f"{block.words['R'][1]} without G2/G3")


def _set_mode(block: Block, state: _State, code: str) -> None:
    state.modes[G_CODES[code].group] = code


def _set_motion(block: Block, state: _State, code: str) -> None:
    state.motion = code


def _dwell(block: Block, state: _State, code: str) -> None:
    """G4 P: a stop of P seconds (as LinuxCNC) before the next move (after the last one at the end).

    The line holds P and nothing else that moves or sets a value (G codes of other groups, M codes and N may
    stand beside it); P is in [0, :data:`MAX_DWELL_S`] s whatever the units (G20 does not scale time).
    """
    others = [raw for letter, (_, raw) in block.words.items() if letter != "P"]
    if "motion" in block.g_codes or others:
        raise block.error(f"G4 with {' '.join(others) or 'G' + block.g_codes['motion']}; G4 takes only P "
                          "(the dwell time, s): give the dwell on its own line")
    if "P" not in block.words:
        raise block.error("G4 without P (the dwell time, s)")
    seconds, raw = block.words["P"]
    if not 0.0 <= seconds <= MAX_DWELL_S:
        raise block.error(f"{raw}: the dwell time P must be in [0, {MAX_DWELL_S:g}] s, got {seconds:g}")
    state.dwells.append(Dwell(len(state.segments), seconds, block.number))


def _path_control(block: Block, state: _State, code: str) -> None:
    """G61 (exact stop, tolerance 0) or G64 P (path tolerance); one value per program once moves began."""
    if code == "64":
        if "P" not in block.words:
            raise block.error("G64 without P (the path tolerance); use G61 for exact stop")
        value, raw = block.words["P"]
        if value <= 0.0:
            raise block.error(f"{raw}: the path tolerance P must be > 0, got {value:g}; use G61 for exact stop")
        tolerance_mm = value * state.scale
    else:
        tolerance_mm = 0.0
    if state.segments and state.tolerance is not None and state.tolerance[0] != tolerance_mm:
        raise block.error(f"G{code} changes the path tolerance set on line {state.tolerance[1]} "
                          f"({state.tolerance[0]:g} mm) to {tolerance_mm:g} mm; one path tolerance per program")
    state.modes["path_control"] = code
    state.tolerance = (tolerance_mm, block.number)


#: What each modal group's G code does to the reader's state.
GROUP_ACTIONS: dict[str, Callable[[Block, _State, str], None]] = {
    "motion": _set_motion, "non_modal": _dwell, "path_control": _path_control,
    **dict.fromkeys(("plane", "units", "work_offset", "distance", "arc_distance", "feed_mode"), _set_mode),
}


def _move(block: Block, state: _State) -> None:
    """The block's move, if it has one."""
    axis_words, offsets = _split_words(block, state)
    if offsets and state.motion not in ("2", "3"):
        raise block.error(f"{' '.join(raw for _, (_, raw) in offsets.items())} without G2/G3")
    arc = state.motion in ("2", "3") and bool(axis_words or offsets or "R" in block.words)
    if not axis_words and not arc:
        return
    if state.motion is None:
        first = next(iter(axis_words.values()))[1]
        raise block.error(f"{first} without a motion mode (G0/G1/G2/G3)")
    target = _target_mm(axis_words, state)
    segment = _arc(block, state, target, offsets) if arc else _line(block, state, target)
    if segment is not None:
        state.segments.append(segment)
    state.position_mm = target


def _split_words(block: Block, state: _State) -> tuple[dict[int, tuple[float, str]], dict[str, tuple[float, str]]]:
    """Axis words by axis index and I/J/K offsets by letter; refuse any other word."""
    axis_words: dict[int, tuple[float, str]] = {}
    offsets: dict[str, tuple[float, str]] = {}
    for letter, word in block.words.items():
        if letter in state.axis_index:
            axis_words[state.axis_index[letter]] = word
        elif letter in OFFSETS:
            offsets[letter] = word
        elif letter not in _IGNORED and letter not in "FPR":
            axes = sorted(state.axis_index)
            raise block.error(f"unsupported word {word[1]} (program axes {axes}, offsets I/J/K)")
    return axis_words, offsets


def _target_mm(axis_words: dict[int, tuple[float, str]], state: _State) -> FloatArray:
    """The move's end, machine mm: absolute words in the work system in force, incremental from here."""
    offset_mm = state.work_offsets_mm[state.modes["work_offset"]]
    incremental = state.modes["distance"] == "91"
    target = state.position_mm.copy()
    for index, (value, _) in axis_words.items():
        target[index] = (target[index] if incremental else offset_mm[index]) + value * state.scale
    return target


def _feed_m_s(block: Block, state: _State) -> float:
    if state.motion == "0":
        return mm_min_to_m_s(state.rapid_feed_mm_min)
    if state.feed_mm_min is None:
        raise block.error(f"G{state.motion} without a feed (F)")
    return mm_min_to_m_s(state.feed_mm_min)


def _line(block: Block, state: _State, target: FloatArray) -> LineSegment | None:
    if float(np.linalg.norm(target - state.position_mm)) < _MIN_MOVE_MM:
        return None
    feed_m_s = _feed_m_s(block, state)
    try:
        return LineSegment(mm_to_m(state.position_mm), mm_to_m(target), feed_m_s, source_line=block.number)
    except ProgramError as err:
        raise block.error(str(err)) from err


def _arc(block: Block, state: _State, target: FloatArray, offsets: dict[str, tuple[float, str]]) -> ArcSegment:
    plane_code = state.modes["plane"]
    letters = PLANES[plane_code]
    missing = [letter for letter in letters if letter not in state.axis_index]
    if missing:
        raise block.error(f"G{state.motion} in plane G{plane_code} needs axes {list(letters)}, "
                          f"program axes are {sorted(state.axis_index)}")
    frame = ArcFrame(state.position_mm, target, (state.axis_index[letters[0]], state.axis_index[letters[1]]),
                     plane_code, state.motion == "2", state.scale, state.work_offsets_mm[state.modes["work_offset"]])
    center = _arc_center(block, state, frame, offsets)
    feed_m_s = _feed_m_s(block, state)
    try:
        return ArcSegment(mm_to_m(state.position_mm), mm_to_m(target), mm_to_m(center), clockwise=frame.clockwise,
                          plane=frame.plane, feed_m_s=feed_m_s, source_line=block.number)
    except ProgramError as err:
        raise block.error(str(err)) from err


def _arc_center(block: Block, state: _State, frame: ArcFrame, offsets: dict[str, tuple[float, str]]) -> FloatArray:
    """The centre (mm) from R or from I/J/K, whichever the block gives (not both)."""
    if "R" in block.words:
        if offsets:
            raise block.error(f"{block.words['R'][1]} and {'/'.join(offsets)} on one line (give R or I/J/K)")
        return center_from_radius(block, frame, block.words["R"])
    if not offsets:
        raise block.error(f"G{state.motion} without I/J/K or R (centre in plane G{frame.plane_code})")
    return center_from_offsets(block, frame, offsets, state.axis_index, state.modes["arc_distance"] == "90.1")
