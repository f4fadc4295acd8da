"""The checks every plant makes before any axis moves: command count, finite commands, the period (ROS-free)."""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from cnc_contour_control.core.errors import FaultError


def check_step(axis_names: Sequence[str], commands: Sequence[float], dt_s: float) -> None:
    """Refuse a step the plant must not take: a wrong command count, a non-finite command (naming its axis), a
    bad ``dt_s``.

    The common case costs one C-level sum (NaN for a NaN or an infinity, or an
    overflow); only a failing sum looks at each command.
    """
    if len(commands) != len(axis_names):
        check_length(axis_names, "commands", commands)
    try:
        total = sum(commands, 0.0)
    except TypeError:
        total = math.nan
    if total - total != 0.0:
        check_commands(axis_names, commands)
    if not (dt_s > 0.0 and dt_s < math.inf):  # also refuses NaN
        raise FaultError(f"plant: dt_s must be finite and > 0, got {dt_s!r}")


def check_commands(axis_names: Sequence[str], commands: Sequence[float]) -> None:
    """Raise :class:`FaultError` naming the first axis whose command is not a finite number."""
    for name, command in zip(axis_names, commands):
        if not is_finite_number(command):
            raise FaultError(f"axis {name}: command must be finite, got {command!r}")


def check_length(axis_names: Sequence[str], name: str, values: Sequence[Any]) -> None:
    """Raise :class:`FaultError` unless ``values`` holds one entry per axis."""
    if len(values) != len(axis_names):
        raise FaultError(f"plant: {name} must have {len(axis_names)} entries {list(axis_names)}, got {len(values)}")


def is_finite_number(value: Any) -> bool:
    """True for a finite real number (False for NaN, an infinity or a non-number)."""
    try:
        return math.isfinite(value)
    except TypeError:
        return False
