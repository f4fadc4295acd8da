"""The in-process engine: the run's stage pipeline stepped sample by sample, without DDS.

Tick k (stamp t_k = k·T, integer nanoseconds as on the wire), in the order of
:data:`cnc_contour_control.core.stages.PIPELINE`:

1. the plant's state at t_k (what ``joint_states(k)`` carries);
2. the interpolator's reference at t_k;
3. (estimator, compensator: when the run has them);
4. each servo's command from the reference and the measured state, with dt
   from the stamps (as the servo node computes it);
5. the plant integrates over T with every axis's command.

Each stage is an :class:`EngineStage` built from :data:`ENGINE_STAGES` by the
stage's name; a stage of the pipeline without an engine implementation is an
error naming it. Stages exchange one :class:`Board` per tick (the in-process
stand-in for the tick's topics) and keep their own series, which become the
:class:`~cnc_tools.run_record.RunRecord` a bag of the same run gives.

Speed: while no feed override can occur (no ``feed_override`` section, no
force regulator), the reference depends on the stamp only and is computed for all ticks at once
with :meth:`Interpolator.sample_array`, which agrees with the node's per-tick
:meth:`Interpolator.sample` to 1e-12 m (``test_engine`` checks it); with a feed
override it is stepped per tick (:class:`~cnc_contour_control.motion.feed_override.LiveReference`,
the request on ``Board.feed_override_request``). The node graph gives the same trajectories
(``test_lockstep_graph_matches_engine_to_1e9``).

A fault during the run (a following-error trip, non-finite data) ends it at that tick, as it ends a graph run:
:class:`EngineFault` carries the record of every tick up to the fault, its summary ``faulted`` with the fault's
message, and the stages' ``finish`` (a learner's state file) is skipped.
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.lockstep import NS_PER_S, duration_to_ns, seconds_to_ns
from cnc_contour_control.core.stages import Pipeline
from cnc_contour_control.motion.interpolation import with_planning_tolerance
from cnc_tools.run_record import BagIntegrity, FloatArray, IntArray, JointStateSeries, RunRecord
from cnc_tools.runs.engine_cross_axis import CompensatorStage, EstimatorStage
from cnc_tools.runs.engine_force import ForceRegulatorStage
from cnc_tools.runs.engine_stages import CORE_STAGES, Board, EngineStage, PlantStage, StageFactory
from cnc_tools.runs.scenario import Scenario

__all__ = ["Board", "EngineFault", "EngineStage", "ENGINE_STAGES", "run_engine", "tick_count", "tick_stamps_s"]

#: Engine implementations of the pipeline's stages, by stage name.
ENGINE_STAGES: dict[str, StageFactory] = {**CORE_STAGES, "estimator": EstimatorStage, "compensator": CompensatorStage,
                                          "force_regulator": ForceRegulatorStage}


class EngineFault(FaultError):
    """A fault ended an engine run at its tick; ``record`` holds every tick before it (its summary ``faulted``).

    A :class:`FaultError`, so a caller that runs many scenarios (a sweep, a tuning, a bench) sees the fault as
    before; the run folder's writer (:func:`cnc_tools.runs.backends.run_on_engine`) keeps the record.
    """

    def __init__(self, message: str, record: RunRecord) -> None:
        super().__init__(message)
        self.record = record

    def __reduce__(self) -> tuple[type[EngineFault], tuple[str, RunRecord]]:
        """Pickled with its record: a pool's worker hands the fault back whole (an exception pickles only its
        ``args``, and a two-argument ``__init__`` could not be called with them: the pool broke)."""
        return (EngineFault, (str(self.args[0]), self.record))


class Clock(Protocol):
    """Wall seconds, only to time the run."""

    def __call__(self) -> float: ...


def tick_count(scenario: Scenario) -> int:
    """Ticks of a run: stamps 0, T, ... up to and including the duration."""
    return duration_to_ns(scenario.duration_s) // seconds_to_ns(scenario.sample_time_s) + 1


def tick_stamps_s(n_ticks: int, sample_ns: int) -> FloatArray:
    """Stamps ``k·T`` of ticks 0..n_ticks-1 as seconds, shape (n_ticks,).

    Converted as :func:`~cnc_contour_control.core.lockstep.ns_to_s` converts each
    integer-nanosecond stamp on the wire (the interpolator node samples there).
    """
    return (np.arange(n_ticks, dtype=np.int64) * sample_ns) * np.float64(1e-9)


def build_stages(scenario: Scenario, pipeline: Pipeline, stamps_ns: IntArray) -> list[EngineStage]:
    """One engine stage per pipeline stage, in tick order; an error names a stage the engine lacks."""
    stages = []
    for stage in pipeline.stages:
        factory = ENGINE_STAGES.get(stage.name)
        if factory is None:
            raise ConfigError(f"stage {stage.name!r} has no engine implementation; "
                              f"the engine runs {sorted(ENGINE_STAGES)}")
        stages.append(factory(scenario, pipeline, stamps_ns))
    return stages


#: Called after the stages answered tick k, before the plant closes it: (the board, the stages). A live view.
TickObserver = Callable[[Board, list[EngineStage]], None]


def run_engine(scenario: Scenario, clock: Callable[[], float] | None = None,
               run_dir: Path | None = None, on_tick: TickObserver | None = None) -> RunRecord:
    """Simulate ``scenario`` in-process and return its run record.

    ``clock`` (wall seconds) only times the run; ``run_dir`` becomes the
    record's ``source`` (where a run folder is written); ``on_tick`` sees every
    tick (``cnc_tools.live.engine`` paces the run and streams it).
    """
    wall = clock or time.perf_counter
    pipeline = scenario.pipeline()
    sample_ns = seconds_to_ns(scenario.sample_time_s)
    stamps_ns = np.arange(tick_count(scenario), dtype=np.int64) * sample_ns
    stages = build_stages(scenario, pipeline, stamps_ns)
    started = wall()
    fault: FaultError | None = None
    try:
        _tick_loop(stages, stamps_ns, sample_ns, on_tick)
    except FaultError as err:
        fault = err
    wall_time_s = wall() - started
    if fault is None:
        for stage in stages:
            stage.finish()
    record = _record(scenario, stages, stamps_ns, wall_time_s, run_dir, fault)
    if fault is not None:
        raise EngineFault(str(fault), record) from fault
    return record


def _tick_loop(stages: list[EngineStage], stamps_ns: IntArray, sample_ns: int,
               on_tick: TickObserver | None = None) -> None:
    """Every tick: the plant's state opens it, the other stages answer in order, the plant closes it.

    The plant's :meth:`PlantStage.advance` closes tick k and opens tick k+1
    (integrate, then read the new state): one call per tick instead of two.
    """
    plant = stages[0]
    if not isinstance(plant, PlantStage):
        raise ConfigError(f"the pipeline must start with the plant, got {type(plant).__name__}")
    board = Board(dt_s=sample_ns / NS_PER_S)
    plant.observe(board)
    answers, advance = [stage.step for stage in stages[1:]], plant.advance
    if on_tick is not None:
        answers.append(lambda board: on_tick(board, stages))
    if len(answers) == 2:  # the core pipeline (interpolator, servos): the same calls, no inner loop
        first, second = answers
        for k, stamp_ns in enumerate(stamps_ns.tolist()):
            board.tick, board.stamp_ns = k, stamp_ns
            first(board)
            second(board)
            advance(board)
        return
    for k, stamp_ns in enumerate(stamps_ns.tolist()):
        board.tick, board.stamp_ns = k, stamp_ns
        for answer in answers:
            answer(board)
        advance(board)


def _record(scenario: Scenario, stages: list[EngineStage], stamps_ns: IntArray, wall_time_s: float,
            run_dir: Path | None, fault: FaultError | None = None) -> RunRecord:
    """The run record of an engine run (every stage contributes its series), cut at the fault's tick if it faulted."""
    parts: dict[str, Any] = {"summary": {}}
    for stage in stages:
        series = stage.series()
        parts["summary"].update(series.pop("summary", {}))
        parts.update(series)
    ticks = int(stamps_ns.size)
    if fault is not None:
        ticks = _ticks_recorded(parts)
        parts = {name: _cut(value, ticks) for name, value in parts.items()}
    simulated_s = (ticks * (stamps_ns[1] - stamps_ns[0]) if ticks > 1 else 0) / NS_PER_S
    ended = {"status": "finished", "faults": []} if fault is None else {
        "status": "faulted", "faults": [str(fault)], "reason": str(fault)}
    summary = {**ended, "ticks": ticks, "simulated_time_s": float(stamps_ns[max(ticks - 1, 0)]) / NS_PER_S,
               "wall_time_s": wall_time_s, "real_time_factor": simulated_s / wall_time_s if wall_time_s > 0 else
               float("nan"), "late_commands": 0, "ran_on": "engine", "ends_by": scenario.ends_by,
               **parts.pop("summary", {})}
    found = dict.fromkeys(scenario.pipeline().per_tick_topics(), ticks)
    integrity = BagIntegrity(True, "engine", found, dict(found), "engine (in-process, no bag)")
    joint_states: JointStateSeries = parts.pop("joint_states")
    return RunRecord(name=scenario.name, source=run_dir or Path("engine"),
                     program=with_planning_tolerance(scenario.program, scenario.interpolator),
                     joint_states=joint_states, integrity=integrity, summary=summary, backend="engine", **parts)


def _series_length(value: Any) -> int | None:
    """Ticks held by a series (its ``stamp_ns``), the fewest of a per-axis mapping; None for anything else."""
    if isinstance(value, dict):
        lengths = [n for n in map(_series_length, value.values()) if n is not None]
        return min(lengths) if lengths else None
    stamps = getattr(value, "stamp_ns", None)
    return None if stamps is None else len(stamps)


def _ticks_recorded(parts: dict[str, Any]) -> int:
    """The ticks every stage recorded whole before a fault stopped the run."""
    lengths = [n for name, value in parts.items() if name != "summary" and (n := _series_length(value)) is not None]
    return min(lengths) if lengths else 0


def _cut(value: Any, ticks: int) -> Any:
    """A series (or a per-axis mapping of them) cut to its first ``ticks`` rows; anything else as it is."""
    if isinstance(value, dict):
        return {key: _cut(item, ticks) for key, item in value.items()}
    stamps = getattr(value, "stamp_ns", None)
    if stamps is None or not dataclasses.is_dataclass(value) or isinstance(value, type):
        return value
    arrays = {f.name: getattr(value, f.name) for f in dataclasses.fields(value)}
    return dataclasses.replace(value, **{name: array[:ticks] for name, array in arrays.items()
                                         if isinstance(array, np.ndarray) and len(array) == len(stamps)})
