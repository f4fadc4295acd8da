"""The engine's stages: each pipeline stage's core objects, stepped in process (no DDS).

A stage answers one tick from the :class:`Board` (the tick's topics in
process) and keeps its own series; :func:`~cnc_tools.runs.engine.run_engine`
steps them in the pipeline's order and collects the series into a run record.
Each stage calls the same core objects with the same floats as its node does
(stamps in integer ns, dt from the stamps, references as the message carries
them), so the node graph and the engine give the same trajectories.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from cnc_contour_control.axis.safety import check_following_error, limit_of
from cnc_contour_control.axis.servo import ServoController, ServoOutput
from cnc_contour_control.core.stages import Pipeline
from cnc_contour_control.motion.feed_override import LiveReference
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.reference_types import ReferenceSample
from cnc_plant_sim.models.machine_faults import tool_positions_m
from cnc_plant_sim.models.plant import make_plant
from cnc_plant_sim.process.cutting import cutting_plant
from cnc_tools.run_record import (
    CommandSeries,
    FloatArray,
    ForceSeries,
    IntArray,
    JointStateSeries,
    ReferenceSeries,
    ToolPositionSeries,
)
from cnc_tools.runs.scenario import Scenario


class Board:
    """One tick's values as the stages hand them on (SI units, axis order).

    Attributes
    ----------
    tick, stamp_ns : int
        Tick index and its stamp.
    dt_s : float
        The period the servos see (from the stamps).
    position_m, velocity_m_s : list of float
        The plant's state at the stamp (``joint_states``).
    ref_position_m, ref_velocity_m_s, ref_acceleration_m_s2 : list of float
        The interpolator's reference (``reference``).
    estimate : ContourEstimate or None
        The estimator's contour error (``contour_error``; None without an estimator).
    compensation : list of float
        The compensator's corrections in drive units (zeros without a compensator).
    commands : list of float
        Every servo's command (``servo/<axis>/command``).
    feed_override_request : float
        The ratio the interpolator is asked for: the latest ``feed_override`` message's ``applied_ratio``
        (a force regulator, stepped after the interpolator, writes it at tick k for tick k+1, as the
        interpolator node takes the previous tick's message); 1 until one arrives.
    feed_override_ratio : float
        The ratio the interpolator applied this tick (``reference.feed_override_ratio``; 1 without override).
    cutting_force_n : float
        The plant's measured cutting force at the stamp (``cutting_force``'s ``force.x``; 0 when it does not cut).
    """

    __slots__ = ("tick", "stamp_ns", "dt_s", "position_m", "velocity_m_s", "ref_position_m", "ref_velocity_m_s",
                 "ref_acceleration_m_s2", "estimate", "compensation", "commands", "feed_override_request",
                 "feed_override_ratio", "cutting_force_n")

    def __init__(self, dt_s: float) -> None:
        self.tick, self.stamp_ns, self.dt_s = 0, 0, dt_s
        self.position_m: list[float] = []
        self.velocity_m_s: list[float] = []
        self.ref_position_m: list[float] = []
        self.ref_velocity_m_s: list[float] = []
        self.ref_acceleration_m_s2: list[float] = []
        self.estimate: Any = None
        self.compensation: list[float] = []
        self.commands: list[float] = []
        self.feed_override_request = 1.0
        self.feed_override_ratio = 1.0
        self.cutting_force_n = 0.0


class EngineStage(Protocol):
    """A stage of the engine: answers a tick from the board, then hands over its series."""

    def step(self, board: Board) -> None:
        """Answer tick ``board.tick``: read the inputs from the board, put the outputs on it."""

    def finish(self) -> None:
        """After the last tick (a learner's run-to-run update, a state file)."""

    def series(self) -> dict[str, Any]:
        """This stage's series for the run record (``RunRecord`` field name -> series; ``summary``: merged)."""


class PlantStage:
    """The plant: opens a tick with its state, closes it by integrating the commands over T."""

    def __init__(self, scenario: Scenario, pipeline: Pipeline, stamps_ns: IntArray) -> None:
        self.plant = make_plant(scenario.plant)
        self.plant.reset(list(scenario.program.start_m))
        self.sample_time_s = scenario.sample_time_s
        self._state = self.plant.state
        self._stamps_ns = stamps_ns
        self._positions: list[float] = []
        self._velocities: list[float] = []
        self._plant_step = self.plant.step  # bound once: advance runs every tick
        self._keep_positions, self._keep_velocities = self._positions.extend, self._velocities.extend
        self._tool: list[float] | None = None
        if scenario.plant.faults.active:  # the tool position (``tool_position``) only with machine faults
            self._tool = []
        self._cutting = cutting_plant(self.plant)  # the cutting force (``cutting_force``) only when it cuts
        self._force: list[float] = []
        if self._tool is not None or self._cutting is not None:
            self.advance = self._advance_with_extras  # type: ignore[method-assign]  # chosen once, per run

    def observe(self, board: Board) -> None:
        """The state at the tick's stamp (what ``joint_states(k)`` carries, and ``tool_position`` if faulted)."""
        board.position_m, board.velocity_m_s = positions, velocities = self._state()
        self._positions.extend(positions)  # flat lists of floats: nothing for the garbage collector to track
        self._velocities.extend(velocities)
        self._observe_extras(board)

    def _observe_extras(self, board: Board) -> None:
        """The tool position (machine faults) and the cutting force (a cutting process) at the tick's stamp."""
        if self._tool is not None:
            self._tool.extend(tool_positions_m(self.plant).tolist())
        if self._cutting is not None:
            board.cutting_force_n = force_n = self._cutting.cutting_force_n()
            self._force.append(force_n)

    def step(self, board: Board) -> None:
        """The plant answers no one within a tick (it opens and closes it)."""

    def advance(self, board: Board) -> None:
        """Close the tick (integrate) and open the next one (its state); the state after the last tick is dropped."""
        self._plant_step(board.commands, self.sample_time_s)
        board.position_m, board.velocity_m_s = positions, velocities = self._state()
        self._keep_positions(positions)
        self._keep_velocities(velocities)

    def _advance_with_extras(self, board: Board) -> None:
        """:meth:`advance` keeping the new tick's tool position and cutting force too (faults, a cut)."""
        self._plant_step(board.commands, self.sample_time_s)
        board.position_m, board.velocity_m_s = positions, velocities = self._state()
        self._keep_positions(positions)
        self._keep_velocities(velocities)
        self._observe_extras(board)

    def finish(self) -> None:
        """Nothing to do after the run."""

    def series(self) -> dict[str, Any]:
        """``joint_states`` (and ``tool_position`` with machine faults) and the plant as drawn (into the summary)."""
        n_axes = len(self.plant.axis_names)
        shape = (min(len(self._positions) // n_axes, len(self._stamps_ns)), n_axes)
        del self._positions[shape[0] * n_axes:], self._velocities[shape[0] * n_axes:]
        out: dict[str, Any] = {"joint_states": JointStateSeries(self._stamps_ns[:shape[0]],
                                                                np.array(self._positions, float).reshape(shape),
                                                                np.array(self._velocities, float).reshape(shape)),
                               "summary": {"plant": self.plant.describe()}}
        if self._tool is not None:
            out["tool_position"] = ToolPositionSeries(self._stamps_ns[:shape[0]],
                                                      np.array(self._tool[:shape[0] * n_axes], float).reshape(shape))
        if self._cutting is not None:
            out["cutting_force"] = force_series(self._stamps_ns[:shape[0]], self._force[:shape[0]])
        return out


def force_series(stamps_ns: IntArray, force_n: list[float]) -> ForceSeries:
    """The ``cutting_force`` series of a plant that cuts: F_c in ``force.x`` (tool frame), the rest 0."""
    force = np.zeros((len(force_n), 3))
    force[:, 0] = force_n
    return ForceSeries(stamps_ns, force, np.zeros((len(force_n), 3)))


class SampledInterpolatorStage:
    """The interpolator stepped per tick at the tick's stamp, as the node does.

    Without an on-line override: :meth:`Interpolator.reference` at the stamp.
    With one (``scenario.override_active``): :meth:`LiveReference.step` towards
    the requested ratio (the schedule's, else ``board.feed_override_request``).
    """

    def __init__(self, scenario: Scenario, pipeline: Pipeline, stamps_ns: IntArray) -> None:
        self.interpolator: Interpolator = scenario.make_interpolator()
        self.live: LiveReference | None = scenario.make_live_reference() if scenario.override_active else None
        self._stamps_ns = stamps_ns
        self._samples: list[ReferenceSample] = []

    def _sample(self, board: Board) -> ReferenceSample:
        """The tick's reference (with the override's applied ratio on the board)."""
        if self.live is None:
            return self.interpolator.reference(board.stamp_ns * 1e-9)
        sample = self.live.step(board.stamp_ns, self.live.request(board.stamp_ns, board.feed_override_request))
        board.feed_override_ratio = sample.feed_override_ratio
        return sample

    def step(self, board: Board) -> None:
        """Put the reference of the tick on the board."""
        sample = self._sample(board)
        self._samples.append(sample)
        board.ref_position_m = sample.position_m.tolist()
        board.ref_velocity_m_s = sample.velocity_m_s.tolist()
        board.ref_acceleration_m_s2 = sample.acceleration_m_s2.tolist()

    def path_fields(self, tick: int) -> tuple[float, int, float, bool]:
        """Tick ``tick``'s path length [m], segment, feed [m/s] and done (the rest of ``reference``; a live view)."""
        x = self._samples[tick]
        return float(x.path_length_m), int(x.segment_index), float(x.feed_m_s), bool(x.done)

    def finish(self) -> None:
        """Nothing to do after the run."""

    def series(self) -> dict[str, Any]:
        """``reference`` as the ``reference`` topic carries it."""
        s = self._samples
        return {"reference": ReferenceSeries(
            self._stamps_ns[:len(s)], np.array([x.position_m for x in s]), np.array([x.velocity_m_s for x in s]),
            np.array([x.acceleration_m_s2 for x in s]), np.array([x.path_length_m for x in s]),
            np.array([x.segment_index for x in s], np.int64), np.array([x.feed_m_s for x in s]),
            np.array([x.done for x in s], bool), np.array([x.feed_override_ratio for x in s], float),
            np.array([x.programmed_feed_m_s for x in s], float))}


class VectorisedInterpolatorStage:
    """The interpolator computed for every tick up front (:meth:`Interpolator.sample_array`), handed out row by row.

    Valid only while the reference depends on the stamp alone: no stage
    upstream of the interpolator (no feed override) in the run.
    """

    def __init__(self, scenario: Scenario, pipeline: Pipeline, stamps_ns: IntArray) -> None:
        self.interpolator: Interpolator = scenario.make_interpolator()
        self._stamps_ns = stamps_ns
        self._trajectory = t = self.interpolator.reference_array(stamps_ns * 1e-9)
        self._rows = iter(list(zip(t.position_m.tolist(), t.velocity_m_s.tolist(), t.acceleration_m_s2.tolist())))

    def step(self, board: Board) -> None:
        """Put the next tick's reference on the board."""
        board.ref_position_m, board.ref_velocity_m_s, board.ref_acceleration_m_s2 = next(self._rows)

    def path_fields(self, tick: int) -> tuple[float, int, float, bool]:
        """Tick ``tick``'s path length [m], segment, feed [m/s] and done (the rest of ``reference``; a live view)."""
        t = self._trajectory
        return (float(t.path_length_m[tick]), int(t.segment_index[tick]), float(t.feed_m_s[tick]),
                bool(t.done[tick]))

    def finish(self) -> None:
        """Nothing to do after the run."""

    def series(self) -> dict[str, Any]:
        """``reference`` as the ``reference`` topic carries it."""
        t = self._trajectory
        return {"reference": ReferenceSeries(self._stamps_ns, t.position_m, t.velocity_m_s, t.acceleration_m_s2,
                                             t.path_length_m, t.segment_index.astype(np.int64), t.feed_m_s, t.done,
                                             np.ones(self._stamps_ns.size))}


def interpolator_stage(scenario: Scenario, pipeline: Pipeline, stamps_ns: IntArray) -> EngineStage:
    """The vectorised interpolator while no feed override can occur, else the sampled one (with the follower)."""
    stage = SampledInterpolatorStage if scenario.override_active else VectorisedInterpolatorStage
    return stage(scenario, pipeline, stamps_ns)


class ServoStage:
    """Every axis's servo: a command per axis from the reference and the measured state."""

    def __init__(self, scenario: Scenario, pipeline: Pipeline, stamps_ns: IntArray) -> None:
        self.servos = [ServoController(config) for config in scenario.servos]
        self._zeros = [0.0] * len(self.servos)
        self._stamps_ns = stamps_ns
        self._parts = [servo.parts for servo in self.servos]
        self._flat: list[float] = []
        self._spindle = [servo for servo in self.servos if servo.spindle is not None]
        self._refusals: list[dict[str, Any]] = []
        self._trips = [(k, limit) for k, limit in enumerate(map(limit_of, scenario.servos)) if limit.active]

    def _check_trips(self, board: Board) -> None:
        """The following-error trip of each axis that has one, after its sample (as the node checks)."""
        for k, limit in self._trips:
            check_following_error(limit, board.ref_position_m[k] - board.position_m[k], board.ref_velocity_m_s[k],
                                  board.stamp_ns)

    def _follow_spindle(self, stamp_ns: int) -> None:
        """The commanded spindle speed to each law that follows it, before the tick (as the node does)."""
        for servo in self._spindle:
            refused = servo.follow_spindle(stamp_ns)
            if refused is not None:  # the node reports it on /diagnostics; the law keeps its last design
                self._refusals.append({"axis": servo.config.axis_name, "stamp_ns": stamp_ns, "reason": refused})

    def step(self, board: Board) -> None:
        """One servo sample per axis; the commands go on the board."""
        if self._spindle:
            self._follow_spindle(board.stamp_ns)
        dt_s, extend = board.dt_s, self._flat.extend  # flat floats: nothing for the garbage collector to track
        board.commands = commands = []
        for parts, r, v, a, x, xv, c in zip(self._parts, board.ref_position_m, board.ref_velocity_m_s,
                                            board.ref_acceleration_m_s2, board.position_m, board.velocity_m_s,
                                            board.compensation or self._zeros):
            row = parts(dt_s, r, v, a, x, xv, c)
            extend(row)
            commands.append(row[0])
        if self._trips:
            self._check_trips(board)

    def latest_parts(self) -> list[dict[str, float]]:
        """The last tick's command parts per axis (:class:`ServoOutput`'s fields; a live view)."""
        width = len(_PARTS)
        rows = self._flat[-width * len(self.servos):]
        return [dict(zip(_PARTS, rows[k * width:(k + 1) * width])) for k in range(len(self.servos))]

    def latest_flat(self) -> list[float]:
        """:meth:`latest_parts` as one list, axis after axis, each in :class:`ServoOutput`'s field order (no dicts:
        the live view's per-tick call)."""
        return self._flat[-len(_PARTS) * len(self.servos):]

    def finish(self) -> None:
        """Nothing to do after the run."""

    def series(self) -> dict[str, Any]:
        """``commands``: one series per axis with the command's parts, as the command topics carry them."""
        per_tick = len(self.servos) * len(_PARTS)
        table = np.array(self._flat, float).reshape(len(self._flat) // per_tick, len(self.servos), len(_PARTS))
        out: dict[str, Any] = {"commands": {servo.config.axis_name: _command_series(servo, table[:, k, :],
                                                                                    self._stamps_ns)
                                            for k, servo in enumerate(self.servos)}}
        if self._spindle:  # how each law followed the spindle (redesigns, refused speeds) into the summary
            out["summary"] = {"spindle_redesigns": {s.config.axis_name: s.spindle.redesigns for s in self._spindle
                                                    if s.spindle is not None},
                              "spindle_refusals": self._refusals}
        return out


#: :class:`ServoOutput`'s fields, the order of :meth:`ServoController.parts`.
_PARTS = tuple(f.name for f in dataclasses.fields(ServoOutput))


def _command_series(servo: ServoController, table: FloatArray, stamps_ns: IntArray) -> CommandSeries:
    """One axis's series from its rows of :meth:`ServoController.parts`, ``table`` (N, 7)."""
    columns: dict[str, np.ndarray] = {name: table[:, k].copy() for k, name in enumerate(_PARTS)}
    columns["saturated"] = columns["saturated"].astype(bool)
    return CommandSeries(axis_name=servo.config.axis_name, law=servo.config.law,
                         command_unit=servo.config.command_unit, stamp_ns=stamps_ns[:len(table)], **columns)


#: A stage factory: (scenario, pipeline, tick stamps) -> engine stage.
StageFactory = Callable[[Scenario, Pipeline, IntArray], EngineStage]

#: Engine implementations of the core stages, by stage name (the engine adds the cross-axis ones).
CORE_STAGES: dict[str, StageFactory] = {
    "plant": PlantStage,
    "interpolator": interpolator_stage,
    "servo": ServoStage,
}
