"""A faulted run as a row of a bench's table: the fault's reason, the axis it names and the time it stopped at.

A bench compares runs; a run the machine stops (a following-error trip, a saturated drive) is a result of the
comparison, not the end of the bench. :func:`fault_row` turns the error that ended a run into a
:class:`FaultRow`, whose :attr:`FaultRow.text` is the cell a table prints.
"""
from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

from cnc_contour_control.core.errors import CncError
from cnc_tools.runs.engine import EngineFault


@dataclass(frozen=True)
class FaultRow:
    """A run's fault: ``reason`` (error type and message), the ``axis`` it names ("" when it names none) and
    ``time_s``, the simulated time of the last tick the run recorded [s] (NaN when it recorded none)."""

    reason: str
    axis: str = ""
    time_s: float = math.nan

    @property
    def text(self) -> str:
        """The fault as a table shows it: axis, time, reason."""
        time_text = f"{self.time_s:.3f} s" if math.isfinite(self.time_s) else "—"
        return f"axis {self.axis or '—'}, t {time_text}: {self.reason}"


def fault_row(err: CncError, axes: Sequence[str]) -> FaultRow:
    """The row of a run that ended on ``err``: its reason, the first of ``axes`` it names, the time it stopped at
    (an :class:`EngineFault` carries the record up to the fault)."""
    named = [axis for axis in axes if re.search(rf"\b(?:servo|axis|plant) {re.escape(axis)}\b", str(err))]
    time_s = math.nan
    if isinstance(err, EngineFault) and err.record.summary.get("ticks", 0) > 0:
        time_s = float(err.record.summary["simulated_time_s"])
    return FaultRow(f"{type(err).__name__}: {err}", named[0] if named else "", time_s)
