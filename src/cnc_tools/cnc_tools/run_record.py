"""The run record: one ROS-free type for every run, whether it came from the node graph's bag or the engine.

Every series a run records, as arrays sorted by stamp (integer nanoseconds,
the header stamps of the graph's messages, ``k·T`` in the engine): the
measured joint states, the interpolator's references, each servo's commands
with their parts, and — when the run has those stages — the estimator's
contour errors, the compensator's corrections and the feed override.
``integrity`` says how completely the series were read (a bag read through its
index or salvaged; an engine run is complete by construction) and ``summary``
is the run's own account (ticks, status, faults, wall time). The scorer,
reports, benches and tuning take a :class:`RunRecord` and never ask where it
came from. No rclpy, no rosbags.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.motion.geometry import Program

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


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
        notes = "".join(f"; {p}" for p in self.problems)
        if self.complete and self.method == "engine":
            return f"complete (engine run in process, {sum(self.found.values())} samples on the per-tick topics{notes})"
        if self.complete:
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
    """Interpolated references: per-axis arrays (N, n_axes); scalars (N,).

    ``feed_override_ratio`` is the override the interpolator applied (1 at the
    programmed feed); None only for a record built without it.
    ``programmed_feed_m_s`` is the current segment's programmed feed, before
    the override; None for a record built without it.
    """

    stamp_ns: IntArray
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray
    path_length_m: FloatArray
    segment_index: IntArray
    feed_m_s: FloatArray
    done: NDArray[np.bool_]
    feed_override_ratio: FloatArray | None = None
    programmed_feed_m_s: FloatArray | None = None


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
class EstimateSeries:
    """The estimator's contour errors (``contour_error`` topic): scalars (N,), per-axis arrays (N, n_axes).

    ``point_a_m``/``point_b_m`` are the two points each estimate used,
    ``window_size``/``window_steps`` the stored points searched and the steps
    walked (0 where a bag of an older run lacks them), ``method`` the estimator.
    """

    stamp_ns: IntArray
    contour_error_m: FloatArray
    tracking_error_m: FloatArray
    segment_index: IntArray
    angle_rad: FloatArray
    point_a_m: FloatArray
    point_b_m: FloatArray
    window_size: IntArray
    window_steps: IntArray
    method: str = ""


@dataclass(frozen=True, eq=False)
class CompensationSeries:
    """The compensator's corrections (``compensation`` topic), (N, n_axes) in ``command_unit``."""

    stamp_ns: IntArray
    correction: FloatArray
    command_unit: str
    learning: BoolArray | None = None
    method: str = ""


@dataclass(frozen=True, eq=False)
class FeedOverrideSeries:
    """The feed override (``feed_override`` topic): requested and applied ratios (N,)."""

    stamp_ns: IntArray
    requested_ratio: FloatArray
    applied_ratio: FloatArray


@dataclass(frozen=True, eq=False)
class ForceSeries:
    """The process force (``cutting_force`` topic, in the tool frame): force (N, 3) [N], torque (N, 3) [N·m]."""

    stamp_ns: IntArray
    force_n: FloatArray
    torque_n_m: FloatArray


@dataclass(frozen=True, eq=False)
class ToolPositionSeries:
    """The tool position (``tool_position`` topic) of a plant with machine faults: (N, n_axes) [m], axis order.

    What a ballbar measures; ``joint_states`` keep the motor side the servo feeds back on.
    """

    stamp_ns: IntArray
    position_m: FloatArray


@dataclass(frozen=True, eq=False)
class RunRecord:
    """One run: program geometry, measured and reference trajectories, commands, optional stage series.

    Attributes
    ----------
    name : str
        The run's name (scenario name, or the bag folder's).
    source : Path
        The bag folder, or the run folder of an engine run (``Path("engine")`` when none).
    program : Program
        The programmed geometry the run followed.
    joint_states, reference, commands
        The per-tick series every run has (``reference`` None only in a bag without it).
    integrity : BagIntegrity
        How completely the series were read.
    contour_error, compensation, feed_override, cutting_force, tool_position
        Series of the optional stages, of a plant that knows its process
        force and of a plant with machine faults; None when the run had none.
    summary : Mapping
        The run's own account: ``ticks``, ``status``, ``faults``, ``wall_time_s``,
        ``real_time_factor``, the plant as drawn (what the plant node writes to
        ``summary.json``; empty for a bag read alone).
    backend : str
        ``"graph"``, ``"engine"`` or ``"bag"`` (read from a bag without its run folder).
    """

    name: str
    source: Path
    program: Program
    joint_states: JointStateSeries
    reference: ReferenceSeries | None
    commands: Mapping[str, CommandSeries]
    integrity: BagIntegrity
    contour_error: EstimateSeries | None = None
    compensation: CompensationSeries | None = None
    feed_override: FeedOverrideSeries | None = None
    cutting_force: ForceSeries | None = None
    tool_position: ToolPositionSeries | None = None
    summary: Mapping[str, Any] = field(default_factory=dict)
    backend: str = "bag"

    @property
    def axis_names(self) -> tuple[str, ...]:
        """Axis order of every per-axis array (the program's)."""
        return tuple(self.program.axis_names)

    @property
    def ticks(self) -> int:
        """Number of joint-state samples (ticks) recorded."""
        return int(self.joint_states.stamp_ns.size)

    @property
    def time_s(self) -> FloatArray:
        """Joint-state stamps in seconds, (N,)."""
        return self.joint_states.stamp_ns * np.float64(1e-9)

    def command_array(self) -> FloatArray:
        """The commands of every axis as (N, n_axes) in axis order (NaN where an axis has none)."""
        out = np.full((self.ticks, len(self.axis_names)), np.nan)
        for k, axis in enumerate(self.axis_names):
            series = self.commands.get(axis)
            if series is not None and series.command.size == self.ticks:
                out[:, k] = series.command
        return out

    def with_(self, **changes: Any) -> RunRecord:
        """A copy with some fields replaced (a relabelled or windowed view)."""
        return dataclasses.replace(self, **changes)


#: The former name of :class:`RunRecord` (bags read before the reshape used it).
RecordedRun = RunRecord
