"""What a running program reports: its feedback, its outcome and its live scores (ROS-free).

:class:`LiveScores` accumulates the contour error (``Program.contour_distance``, the scorer's) and the
following error tick by tick for :class:`~cnc_contour_control.motion.program_session.ProgramSession`;
:class:`ProgramFeedback` and :class:`ProgramOutcome` are the RunProgram feedback and result in SI units.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cnc_contour_control.motion.geometry import FloatArray, Program

#: Measured positions scored by one call of Program.contour_distance.
SCORE_BATCH = 64
#: The same while a contour tolerance is checked (a violation is seen at most this many ticks late).
CONTOUR_CHECK_BATCH = 4


@dataclass(frozen=True)
class ProgramFeedback:
    """Progress of the running program (the RunProgram feedback; SI units)."""

    line_number: int
    segment_index: int
    path_length_m: float
    total_length_m: float
    feed_m_s: float
    feed_override_ratio: float
    contour_error_m: float
    following_error_m: float
    elapsed_s: float


@dataclass(frozen=True)
class ProgramOutcome:
    """How a program ended and its scores (the RunProgram result; SI units).

    ``outcome`` is one of :data:`OUTCOMES`; errors are NaN for a program
    that never ticked.
    """

    outcome: str
    reason: str
    program_name: str
    max_contour_error_m: float
    rms_contour_error_m: float
    max_following_error_m: float
    cycle_time_s: float
    path_length_m: float
    total_length_m: float
    ticks: int


class LiveScores:
    """Contour and following error of the measured positions, accumulated tick by tick.

    Parameters
    ----------
    program : Program or None
        The program as written; the contour error is ``program.contour_distance``
        (the scorer's), computed in batches of ``batch`` positions (None: no contour, NaN).
    contour_limit_m : float
        The contour tolerance, m (inf: not checked); the first tick beyond it is kept in ``beyond``.
    """

    def __init__(self, program: Program | None, batch: int = SCORE_BATCH, contour_limit_m: float = math.inf) -> None:
        self.program, self.batch = program, int(batch)
        self.contour_limit_m = float(contour_limit_m)
        self.beyond: tuple[float, Any] | None = None  # (distance m, the tick's tag given to add) of the first
        self._tags: list[Any] = []
        self._pending: list[FloatArray] = []
        self.ticks = 0
        self.max_contour_m = self.max_following_m = 0.0
        self.latest_contour_m = self.latest_following_m = math.nan
        self._sum_square_m2 = 0.0
        self._scored = 0

    def add(self, position_m: FloatArray, reference_m: FloatArray, tag: Any = None) -> None:
        """One tick: the measured position and the reference at the same stamp, m, shape ``(n_axes,)``; ``tag``
        comes back in ``beyond`` if this tick's contour error is the first beyond the tolerance."""
        self.latest_following_m = float(np.max(np.abs(reference_m - position_m)))
        self.max_following_m = max(self.max_following_m, self.latest_following_m)
        if self.program is None:
            self.ticks += 1
            return
        self._pending.append(np.array(position_m, dtype=float))
        self._tags.append(tag)
        self.ticks += 1
        if len(self._pending) >= self.batch:
            self.flush()

    def flush(self) -> None:
        """Score the positions not yet scored."""
        if not self._pending:
            return
        assert self.program is not None, "add() keeps no position without a program"
        distance_m, _ = self.program.contour_distance(np.vstack(self._pending))
        if self.beyond is None and float(np.max(distance_m)) > self.contour_limit_m:
            first = int(np.argmax(distance_m > self.contour_limit_m))
            self.beyond = (float(distance_m[first]), self._tags[first])
        self._pending.clear()
        self._tags.clear()
        self.max_contour_m = max(self.max_contour_m, float(np.max(distance_m)))
        self._sum_square_m2 += float(np.dot(distance_m, distance_m))
        self._scored += distance_m.size
        self.latest_contour_m = float(distance_m[-1])

    @property
    def rms_contour_m(self) -> float:
        """Root mean square of the contour error over the scored ticks, m (NaN before any)."""
        self.flush()
        return math.sqrt(self._sum_square_m2 / self._scored) if self._scored else math.nan
