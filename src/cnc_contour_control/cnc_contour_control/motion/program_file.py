"""Read a part program from a file: a YAML program (or a scenario holding one) or G-code."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from cnc_contour_control.core.config import read_yaml_mapping
from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.motion.gcode_file import not_a_file
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.program import load_program

#: File endings read as G-code; anything else is YAML.
GCODE_SUFFIXES = (".ngc", ".nc", ".gcode", ".tap", ".cnc")


def read_program_file(path: str | Path, axes: tuple[str, ...] | None = None) -> Program:
    """Load the program in ``path``.

    A YAML file holds either a program mapping or a scenario with a
    ``program:`` key. A G-code file is parsed for ``axes`` (default x, y, z).
    """
    file = Path(path)
    reason = not_a_file(file, "program_file")
    if reason is not None:
        raise ProgramError(reason)
    if file.suffix.lower() in GCODE_SUFFIXES:
        body: dict[str, Any] = {"gcode_file": str(file)}
        if axes:
            body["axes"] = list(axes)
        return load_program(body, name=file.stem, base_dir=file.parent)
    return load_program(_yaml_program(file), name=file.stem, base_dir=file.parent)


def _yaml_program(file: Path) -> dict[str, Any]:
    content = read_yaml_mapping(file, "program_file", ProgramError)
    program = content.get("program", content)
    if not isinstance(program, dict):
        raise ProgramError(f"program in {str(file)!r} must be a mapping")
    return program
