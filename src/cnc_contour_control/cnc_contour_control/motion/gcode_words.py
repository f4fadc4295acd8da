"""Reading G-code lines into blocks: words by letter, G codes by modal group, comments dropped.

A line is ASCII outside its comments: ``float`` reads Unicode digits
(``X١٢`` would be 12 mm), so any other character is refused. G codes come
from the table :data:`G_CODES` (a code's text, e.g. ``"90.1"``, to its modal
group, or to the reason it is refused); M codes other than the program ends
:data:`PROGRAM_END_M` are read and ignored. Interpretation is in
:mod:`cnc_contour_control.motion.gcode`.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from cnc_contour_control.core.errors import ProgramError


@dataclass(frozen=True)
class GCode:
    """A G code's modal group (``non_modal`` for G4), or the reason it is refused."""

    group: str
    refusal: str | None = None


def _group(group: str, *codes: str) -> dict[str, GCode]:
    return {code: GCode(group) for code in codes}


#: Supported (and knowingly refused) G codes by their text, e.g. ``"1"`` for G1 and G01, ``"90.1"``.
G_CODES: dict[str, GCode] = {
    **_group("motion", "0", "1", "2", "3"), **_group("non_modal", "4"),
    **_group("plane", "17", "18", "19"), **_group("units", "20", "21"),
    **_group("work_offset", "54", "55", "56", "57", "58", "59"), **_group("path_control", "61", "64"),
    **_group("distance", "90", "91"), **_group("arc_distance", "90.1", "91.1"), **_group("feed_mode", "94"),
    "93": GCode("feed_mode", "G93 (inverse-time feed) is not supported: give F in mm/min under G94"),
}
#: M codes that end the program (M2, M30); nothing after them runs.
PROGRAM_END_M = frozenset({2, 30})
_WORD = re.compile(r"\s*([A-Za-z])\s*([-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+))", re.ASCII)
_COMMENT = re.compile(r"\([^()]*\)")


@dataclass
class Block:
    """The words of one line: G codes by modal group, M codes, and every other word by letter.

    ``number`` is the line of the text (1-based); ``label`` the N word if any.
    """

    number: int
    label: str | None = None
    g_codes: dict[str, str] = field(default_factory=dict)
    m_codes: list[int] = field(default_factory=list)
    words: dict[str, tuple[float, str]] = field(default_factory=dict)

    def error(self, message: str) -> ProgramError:
        """A :class:`ProgramError` naming this line (and its N word)."""
        where = f"line {self.number}" if self.label is None else f"line {self.number} ({self.label})"
        return ProgramError(f"{where}: {message}")

    @property
    def empty(self) -> bool:
        """True for a line without words (blank, comment, ``%``)."""
        return not (self.g_codes or self.m_codes or self.words or self.label)

    def first_word(self) -> str:
        """Some word of the block as written, for messages."""
        if self.words:
            return next(iter(self.words.values()))[1]
        if self.g_codes:
            return f"G{next(iter(self.g_codes.values()))}"
        return f"M{self.m_codes[0]}" if self.m_codes else str(self.label)


def read_block(line: str, number: int) -> Block:
    """Split one line (number ``number``, 1-based) into words, dropping comments.

    Raises
    ------
    ProgramError
        For an unbalanced comment, a non-ASCII character, an unreadable or
        unsupported word, or a word or modal group given twice.
    """
    block = Block(number)
    text = _COMMENT.sub(" ", line).split(";", 1)[0].strip()
    if "(" in text or ")" in text:
        raise block.error(f"unbalanced comment in {line.strip()!r}")
    if not text.isascii():
        char = next(c for c in text if not c.isascii())
        raise block.error(f"non-ASCII character {char!r} (U+{ord(char):04X}) in {text!r}: "
                          "G-code words are ASCII letters and digits")
    if text.startswith("%"):  # the tape's start or end mark, alone on its line
        if text != "%":
            raise block.error(f"text after % in {text!r} (% marks the start or end of the program, alone on its line)")
        return block
    position = 0
    while position < len(text):
        match = _WORD.match(text, position)
        if match is None:
            raise block.error(f"cannot read {text[position:].strip()!r}")
        _add_word(block, match.group(1).upper(), match.group(2))
        position = match.end()
    return block


def _add_word(block: Block, letter: str, value_text: str) -> None:
    value, raw = float(value_text), f"{letter}{value_text}"
    if not math.isfinite(value):  # over 309 digits: float() gives infinity
        raise block.error(f"{raw[:20]}...: a value of {len(value_text)} characters is beyond any number "
                          "(> 1.8e308)")
    if letter == "G":
        _add_g_code(block, value, raw)
    elif letter == "M":
        if value != int(value):
            raise block.error(f"unsupported word {raw} (M codes are whole numbers)")
        block.m_codes.append(int(value))
    elif letter == "N":
        block.label = raw
    elif letter in block.words:
        raise block.error(f"word {letter} twice ({block.words[letter][1]} and {raw})")
    else:
        block.words[letter] = (value, raw)


def _add_g_code(block: Block, value: float, raw: str) -> None:
    code = f"{value:g}"
    entry = G_CODES.get(code)
    if entry is None:
        supported = [f"G{c}" for c, e in G_CODES.items() if e.refusal is None]
        raise block.error(f"unsupported word {raw} (supported: {supported})")
    if entry.refusal is not None:
        raise block.error(f"{raw}: {entry.refusal}")
    if entry.group in block.g_codes:
        raise block.error(f"G{block.g_codes[entry.group]} and {raw} on one line (same modal group)")
    block.g_codes[entry.group] = code
