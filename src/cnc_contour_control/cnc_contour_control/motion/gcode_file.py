"""A G-code file's bytes into text as shops write them: UTF-8, else an 8-bit code page (ROS-free).

Controllers and CAM post-processors write comments in the shop's 8-bit code
page (``(Fräser Ø 6 mm)`` in Latin-1), so a file that is not UTF-8 is read as
Latin-1, which maps every byte to one character: the comment keeps its bytes
and the reader (:mod:`cnc_contour_control.motion.gcode_words`) refuses any
non-ASCII character outside a comment, naming its line. A NUL byte marks a
binary file and is refused; so are a missing path, a directory, a file over
:data:`~cnc_contour_control.core.config.MAX_INPUT_FILE_BYTES` and one that
cannot be read, each with the reason.
"""
from __future__ import annotations

from pathlib import Path

from cnc_contour_control.core.config import MAX_INPUT_FILE_BYTES, read_bounded_bytes
from cnc_contour_control.core.errors import CncError, ProgramError

#: The code page of a G-code file that is not UTF-8 (every byte is a character).
FALLBACK_ENCODING = "latin-1"


def not_a_file(path: str | Path, what: str) -> str | None:
    """Why ``path`` is no regular file (``"... is a directory"``, ``"... does not exist"``), or None if it is one."""
    file = Path(path)
    if file.is_file():
        return None
    if file.is_dir():
        return f"{what} {str(file)!r} is a directory, not a file"
    if file.exists():
        return f"{what} {str(file)!r} is not a regular file"
    return f"{what} {str(file)!r} does not exist"


def decode_gcode(data: bytes, what: str = "G-code", error: type[CncError] = ProgramError) -> str:
    """The text of a G-code file's ``data``: UTF-8, else Latin-1; ``error`` naming ``what`` for a NUL byte."""
    nul = data.find(b"\0")
    if nul >= 0:
        raise error(f"{what} is not a text file (NUL byte at offset {nul})")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode(FALLBACK_ENCODING)


def read_gcode_file(path: str | Path, what: str = "program_file", error: type[CncError] = ProgramError,
                    limit_bytes: int = MAX_INPUT_FILE_BYTES) -> str:
    """The text of the G-code file ``path`` (see the module notes); ``error`` naming ``what``, the file and why not."""
    file = Path(path)
    reason = not_a_file(file, what)
    if reason is not None:
        raise error(reason)
    return decode_gcode(read_bounded_bytes(file, what, error, limit_bytes), f"{what} {str(file)!r}", error)
