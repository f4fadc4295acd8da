"""Views of a streaming plan by global segment index, whatever it has forgotten behind the tool (ROS-free)."""
from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.motion.geometry import Segment


class SegmentStore(Protocol):
    """What the views read: the kept segments, the global index of the first, the count with forgotten ones."""

    segments: list[Segment]
    base: int

    @property
    def count(self) -> int: ...


class PlannedSegments:
    """The planned segments so far by global index (``len``: all of them, forgotten ones included)."""

    def __init__(self, blocks: SegmentStore) -> None:
        self._blocks = blocks

    def __len__(self) -> int:
        return self._blocks.count

    def __getitem__(self, index: int) -> Segment:
        blocks = self._blocks
        if index < 0:
            return blocks.segments[index]
        if index < blocks.base:
            raise ProgramError(f"planned segment {index} was forgotten (kept from {blocks.base}): sampled behind the "
                               "tool")
        return blocks.segments[index - blocks.base]


class ShiftedColumn:
    """A kept column indexed by global segment index (``int`` or an int array)."""

    def __init__(self, column: np.ndarray, base: int) -> None:
        self._column, self._base = column, base

    def __getitem__(self, index: Any) -> Any:
        return self._column[np.asarray(index) - self._base]
