"""A G-code subset reader: G0/G1/G2/G3 moves into a :class:`~cnc_contour_control.geometry.Program`.

Supported: G0 (line at the rapid feed given as a parameter), G1, G2/G3 (arcs
with incremental I/J/K centre offsets, full circles, helices), G17/G18/G19
planes (XY, ZX, YZ; arc direction seen from +Z, +Y, +X), G20/G21 inch/mm,
G90/G91 absolute/incremental, G94 (feed per minute, the only mode), F in
mm/min (inch/min under G20), comments ``( )`` and ``;``, ``%`` lines and line
numbers N. M, S and T words (spindle, tool) are accepted and ignored. Any
other word is an error. Moves that do not move are skipped. Errors name the
line of the text (1-based) and the offending word, e.g. ``line 7: G2 without I/J/K``.
"""
from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from cnc_contour_control.config import require_positive
from cnc_contour_control.errors import ConfigError, ProgramError
from cnc_contour_control.geometry import ArcSegment, FloatArray, LineSegment, Program, Segment
from cnc_contour_control.units import mm_min_to_m_s, mm_to_m

MM_PER_INCH = 25.4
#: Supported G codes and their modal group.
G_CODES: dict[int, str] = {0: "motion", 1: "motion", 2: "motion", 3: "motion",
                           17: "plane", 18: "plane", 19: "plane", 20: "units", 21: "units",
                           90: "distance", 91: "distance", 94: "feed_mode"}
#: Plane code -> the axis letters spanning it, in the order that defines the arc direction.
PLANES: dict[int, tuple[str, str]] = {17: ("X", "Y"), 18: ("Z", "X"), 19: ("Y", "Z")}
#: Centre-offset letter -> the axis letter it offsets.
OFFSETS: dict[str, str] = {"I": "X", "J": "Y", "K": "Z"}
_IGNORED = frozenset("NMST")
_RESERVED = frozenset("GFIJKNMSTOPRLQDEH")
_WORD = re.compile(r"\s*([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\([^()]*\)")
_MIN_MOVE_MM = 1.0e-9


@dataclass
class _State:
    """The modal state of the reader; positions in mm."""

    position_mm: FloatArray
    axis_index: dict[str, int]
    rapid_feed_mm_min: float
    motion: int | None = None
    plane: int = 17
    inch: bool = False
    incremental: bool = False
    feed_mm_min: float | None = None
    segments: list[Segment] = field(default_factory=list)


@dataclass
class _Block:
    """The words of one line: G codes by modal group, and every other word by letter."""

    number: int
    g_codes: dict[str, int] = field(default_factory=dict)
    words: dict[str, tuple[float, str]] = field(default_factory=dict)

    def error(self, message: str) -> ProgramError:
        return ProgramError(f"line {self.number}: {message}")


def parse_gcode(text: str, axes: Sequence[str] = ("x", "y", "z"), *, rapid_feed_mm_min: float = 1000.0,
                start_mm: Sequence[float] | None = None, name: str = "gcode") -> Program:
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
        Position before the first move, mm, one per axis (default: origin).
    name : str
        Program name.

    Raises
    ------
    ProgramError
        On a malformed or unsupported line, naming the line and the word.
    """
    axis_names = _check_axes(axes)
    start = np.zeros(len(axis_names)) if start_mm is None else np.array(start_mm, dtype=float)
    if start.shape != (len(axis_names),) or not np.all(np.isfinite(start)):
        raise ConfigError(f"start_mm must be {len(axis_names)} finite numbers, got {start_mm!r}")
    state = _State(start, {n.upper(): i for i, n in enumerate(axis_names)},
                   require_positive("rapid_feed_mm_min", rapid_feed_mm_min))
    for number, line in enumerate(text.splitlines(), start=1):
        block = _read_block(line, number)
        if block.g_codes or block.words:
            _execute(block, state)
    if not state.segments:
        raise ProgramError(f"{name}: the G-code has no motion")
    return Program(name, axis_names, tuple(state.segments))


def _check_axes(axes: Sequence[str]) -> tuple[str, ...]:
    names = tuple(axes) if not isinstance(axes, str) else (axes,)
    bad = [n for n in names if not (isinstance(n, str) and len(n) == 1 and n.isalpha()) or n.upper() in _RESERVED]
    if not names or bad or len({n.upper() for n in names}) != len(names):
        raise ConfigError(
            f"axes must be distinct single letters other than {sorted(_RESERVED)}, got {list(names)}")
    return names


def _read_block(line: str, number: int) -> _Block:
    """Split one line into words, dropping comments."""
    block = _Block(number)
    text = _COMMENT.sub(" ", line).split(";", 1)[0].strip()
    if "(" in text or ")" in text:
        raise block.error(f"unbalanced comment in {line.strip()!r}")
    if text.startswith("%"):
        return block
    position = 0
    while position < len(text):
        match = _WORD.match(text, position)
        if match is None:
            raise block.error(f"cannot read {text[position:].strip()!r}")
        _add_word(block, match.group(1).upper(), match.group(2))
        position = match.end()
    return block


def _add_word(block: _Block, letter: str, value_text: str) -> None:
    value, raw = float(value_text), f"{letter}{value_text}"
    if letter == "G":
        code = int(value) if value == int(value) else -1
        group = G_CODES.get(code)
        if group is None:
            raise block.error(f"unsupported word {raw} (supported: {[f'G{c}' for c in sorted(G_CODES)]})")
        if group in block.g_codes:
            raise block.error(f"G{block.g_codes[group]} and {raw} on one line (same modal group)")
        block.g_codes[group] = code
    elif letter in block.words:
        raise block.error(f"word {letter} twice ({block.words[letter][1]} and {raw})")
    else:
        block.words[letter] = (value, raw)


def _execute(block: _Block, state: _State) -> None:
    """Apply the modal codes and the feed of ``block``, then its move (if any)."""
    codes = block.g_codes
    state.plane = codes.get("plane", state.plane)
    state.inch = codes.get("units", 20 if state.inch else 21) == 20
    state.incremental = codes.get("distance", 91 if state.incremental else 90) == 91
    state.motion = codes.get("motion", state.motion)
    axis_words, offsets = _split_words(block, state)
    if "F" in block.words:
        feed, raw = block.words["F"]
        if feed <= 0.0:
            raise block.error(f"{raw}: F must be > 0, got {feed:g}")
        state.feed_mm_min = feed * (MM_PER_INCH if state.inch else 1.0)
    if offsets and state.motion not in (2, 3):
        raise block.error(f"{' '.join(raw for _, (_, raw) in offsets.items())} without G2/G3")
    arc = state.motion in (2, 3) and bool(axis_words or offsets)
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


def _split_words(block: _Block, state: _State) -> tuple[dict[int, tuple[float, str]], dict[str, tuple[float, str]]]:
    """Axis words by axis index and I/J/K offsets by letter; refuse any other word."""
    axis_words: dict[int, tuple[float, str]] = {}
    offsets: dict[str, tuple[float, str]] = {}
    for letter, word in block.words.items():
        if letter in state.axis_index:
            axis_words[state.axis_index[letter]] = word
        elif letter in OFFSETS:
            offsets[letter] = word
        elif letter not in _IGNORED and letter != "F":
            axes = sorted(state.axis_index)
            raise block.error(f"unsupported word {word[1]} (program axes {axes}, offsets I/J/K)")
    return axis_words, offsets


def _target_mm(axis_words: dict[int, tuple[float, str]], state: _State) -> FloatArray:
    scale = MM_PER_INCH if state.inch else 1.0
    target = state.position_mm.copy()
    for index, (value, _) in axis_words.items():
        target[index] = (target[index] if state.incremental else 0.0) + value * scale
    return target


def _feed_m_s(block: _Block, state: _State) -> float:
    if state.motion == 0:
        return mm_min_to_m_s(state.rapid_feed_mm_min)
    if state.feed_mm_min is None:
        raise block.error(f"G{state.motion} without a feed (F)")
    return mm_min_to_m_s(state.feed_mm_min)


def _line(block: _Block, state: _State, target: FloatArray) -> LineSegment | None:
    if float(np.linalg.norm(target - state.position_mm)) < _MIN_MOVE_MM:
        return None
    feed_m_s = _feed_m_s(block, state)
    try:
        return LineSegment(mm_to_m(state.position_mm), mm_to_m(target), feed_m_s)
    except ProgramError as err:
        raise block.error(str(err)) from err


def _arc(block: _Block, state: _State, target: FloatArray, offsets: dict[str, tuple[float, str]]) -> ArcSegment:
    letters = PLANES[state.plane]
    missing = [letter for letter in letters if letter not in state.axis_index]
    if missing:
        raise block.error(f"G{state.motion} in plane G{state.plane} needs axes {list(letters)}, "
                          f"program axes are {sorted(state.axis_index)}")
    allowed = {k for k, v in OFFSETS.items() if v in letters}
    for letter, (_, raw) in offsets.items():
        if letter not in allowed:
            raise block.error(f"{raw} is not allowed in plane G{state.plane} (use {'/'.join(sorted(allowed))})")
    if not offsets:
        raise block.error(f"G{state.motion} without I/J/K (centre offset in plane G{state.plane})")
    plane = (state.axis_index[letters[0]], state.axis_index[letters[1]])
    center = state.position_mm.copy()
    scale = MM_PER_INCH if state.inch else 1.0
    for letter, (value, _) in offsets.items():
        center[state.axis_index[OFFSETS[letter]]] += value * scale
    feed_m_s = _feed_m_s(block, state)
    try:
        return ArcSegment(mm_to_m(state.position_mm), mm_to_m(target), mm_to_m(center),
                          clockwise=state.motion == 2, plane=plane, feed_m_s=feed_m_s)
    except ProgramError as err:
        raise block.error(str(err)) from err
