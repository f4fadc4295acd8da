"""A recorded run as arrays: the series read from a bag and how intact the bag was (no rclpy)."""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.geometry import Program

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class BagIntegrity:
    """How a bag was read and what, if anything, is missing.

    Attributes
    ----------
    complete
        True only when the file was read through its intact index and every topic
        read holds as many messages as expected.
    method
        ``"index"`` (rosbags through the MCAP summary) or ``"scan"`` (record-by-record salvage).
    found
        Messages read per topic (the topics ``read_bag`` decodes).
    expected
        Messages the writer recorded per topic, or ``None`` when unknown.
    expected_source
        ``"metadata.yaml"``, ``"mcap summary"`` or ``"unknown"``.
    problems
        What went wrong, in words; empty for a complete bag.
    """

    complete: bool
    method: str
    found: Mapping[str, int]
    expected: Mapping[str, int] | None
    expected_source: str
    problems: tuple[str, ...] = ()

    @property
    def lost(self) -> dict[str, int] | None:
        """Messages missing per topic (expected - found), or ``None`` when the count is unknown."""
        if self.expected is None:
            return None
        return {topic: max(self.expected.get(topic, 0) - count, 0) for topic, count in self.found.items()}

    def describe(self) -> str:
        """One line for people: complete, or what was lost."""
        if self.complete:
            notes = "".join(f"; {p}" for p in self.problems)
            return f"complete ({sum(self.found.values())} messages read through the index{notes})"
        lost = self.lost
        if lost is None:
            loss = "count of lost messages unknown (no metadata.yaml, no MCAP summary)"
        elif any(lost.values()):
            loss = f"{sum(lost.values())} messages lost ({', '.join(f'{t}: {n}' for t, n in lost.items() if n)})"
        else:
            loss = f"no messages lost (all {sum(self.found.values())} expected were recovered)"
        return f"INCOMPLETE, read by {self.method}: {loss}; " + "; ".join(self.problems)


@dataclass(frozen=True, eq=False)
class JointStateSeries:
    """Measured axis states. ``stamp_ns`` (N,) int64 header stamps; arrays (N, n_axes) in run axis order."""

    stamp_ns: IntArray
    position_m: FloatArray
    velocity_m_s: FloatArray


@dataclass(frozen=True, eq=False)
class ReferenceSeries:
    """Interpolated references: per-axis arrays (N, n_axes); scalars (N,)."""

    stamp_ns: IntArray
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray
    path_length_m: FloatArray
    segment_index: IntArray
    feed_m_s: FloatArray
    done: NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class CommandSeries:
    """One axis's servo commands (N,) in ``command_unit``; ``error_m`` the following error, m."""

    axis_name: str
    law: str
    command_unit: str
    stamp_ns: IntArray
    command: FloatArray
    feedback: FloatArray
    feedforward: FloatArray
    compensation: FloatArray
    disturbance_estimate: FloatArray
    saturated: NDArray[np.bool_]
    error_m: FloatArray


@dataclass(frozen=True, eq=False)
class RecordedRun:
    """A run read from a bag: program geometry, measured and reference trajectories, commands."""

    name: str
    source: Path
    program: Program
    joint_states: JointStateSeries
    reference: ReferenceSeries | None
    commands: Mapping[str, CommandSeries]
    integrity: BagIntegrity

    @property
    def axis_names(self) -> tuple[str, ...]:
        """Axis order of every per-axis array (the program's)."""
        return tuple(self.program.axis_names)
