"""The engine's cross-axis stages: the contour-error estimator and the compensator, stepped in process.

Each calls the same core object with the same floats as its node (the
reference and the measured positions of the tick, the stamps' dt), so the node
graph and the engine give the same trajectories. The compensator's run-to-run
update and its state file are made in :meth:`CompensatorStage.finish`, after
the last tick, as the node makes them when the plant announces the end.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from cnc_contour_control.compensators import CompensatorSample
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.stages import Pipeline
from cnc_tools.run_record import CompensationSeries, EstimateSeries, IntArray
from cnc_tools.runs.engine_stages import Board
from cnc_tools.runs.scenario import Scenario


class EstimatorStage:
    """The contour-error estimator: one estimate per tick from the reference and the measured positions."""

    def __init__(self, scenario: Scenario, pipeline: Pipeline, stamps_ns: IntArray) -> None:
        if scenario.estimator is None:
            raise ConfigError("the pipeline has an estimator stage but the scenario no estimator section")
        self.method = scenario.estimator.method
        self.estimator = scenario.estimator.make(scenario.program)
        self._stamps_ns = stamps_ns
        self._estimates: list[Any] = []

    def step(self, board: Board) -> None:
        """Put the tick's estimate on the board."""
        board.estimate = estimate = self.estimator.step(board.ref_position_m, board.position_m)
        self._estimates.append(estimate)

    def finish(self) -> None:
        """Nothing to do after the run."""

    def series(self) -> dict[str, Any]:
        """``contour_error`` as the topic carries it."""
        e = self._estimates
        return {"contour_error": EstimateSeries(
            self._stamps_ns[:len(e)], np.array([x.contour_error_m for x in e], float),
            np.array([x.tracking_error_m for x in e], float).reshape(len(e), -1),
            np.array([x.segment_index for x in e], np.int64), np.array([x.angle_rad for x in e], float),
            np.array([x.point_a_m for x in e], float).reshape(len(e), -1),
            np.array([x.point_b_m for x in e], float).reshape(len(e), -1),
            np.array([x.window_size for x in e], np.int64), np.array([x.steps for x in e], np.int64), self.method)}


class CompensatorStage:
    """The compensator: one correction per axis per tick, learning online; its state saved after the run."""

    def __init__(self, scenario: Scenario, pipeline: Pipeline, stamps_ns: IntArray) -> None:
        if scenario.compensator is None:
            raise ConfigError("the pipeline has a compensator stage but the scenario no compensator section")
        self.settings = scenario.compensator
        self.compensator = self.settings.make(scenario.axes, scenario.sample_time_s)
        self.command_unit = scenario.servos[0].command_unit
        self._stamps_ns = stamps_ns
        self._sample = CompensatorSample()
        self._corrections: list[float] = []
        self._learning: list[bool] = []
        self.summary: dict[str, Any] = {}

    def step(self, board: Board) -> None:
        """Put the tick's corrections on the board (the servos add them)."""
        sample, estimate = self._sample, board.estimate
        sample.tick, sample.dt_s = board.tick, board.dt_s
        sample.position_m, sample.ref_position_m = board.position_m, board.ref_position_m
        sample.contour_error_m, sample.angle_rad = estimate.contour_error_m, estimate.angle_rad
        sample.tracking_error_m = list(estimate.tracking_error_m)
        board.compensation = correction = self.compensator.step(sample)
        self._corrections.extend(correction)
        self._learning.append(not self.compensator.frozen and self.compensator.fault is None)

    def finish(self) -> None:
        """The run-to-run update and the state file, as the node makes them when the run finishes."""
        saved = self.settings.finish(self.compensator)
        self.summary = {"method": self.settings.method, "fault": self.compensator.fault,
                        "state_out": None if saved is None else str(saved)}

    def series(self) -> dict[str, Any]:
        """``compensation`` as the topic carries it, and the compensator's end in the summary."""
        n = len(self._learning)
        return {"compensation": CompensationSeries(
            self._stamps_ns[:n], np.array(self._corrections, float).reshape(n, -1), self.command_unit,
            np.array(self._learning, bool), self.settings.method),
            "summary": {"compensator": self.summary}}
