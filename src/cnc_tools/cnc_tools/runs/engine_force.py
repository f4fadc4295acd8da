"""The force regulator in the engine: the node's core object, stepped where the pipeline puts it (no DDS).

Tick k: the plant's measured cutting force at t_k is on the board
(``cutting_force(k)``); the regulator turns it into the override of tick k
(``feed_override(k)``), which the interpolator takes at tick k+1 (the node's
``previous_tick`` source: the message of the tick before, waited for). The
stage is stepped after the servos, so the board's ``feed_override_request``
it writes is read one tick later, as on the wire. dt is the stamps'
difference (the nominal period at tick 0), as the node computes it.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.stages import Pipeline
from cnc_tools.run_record import FeedOverrideSeries, IntArray
from cnc_tools.runs.engine_stages import Board
from cnc_tools.runs.scenario import Scenario


class ForceRegulatorStage:
    """``cutting_force`` -> :class:`~cnc_contour_control.force.ForceRegulator` -> ``feed_override``."""

    def __init__(self, scenario: Scenario, pipeline: Pipeline, stamps_ns: IntArray) -> None:
        settings = scenario.force_regulator
        if settings is None:
            raise ConfigError("the force_regulator stage runs only with a scenario.force_regulator section")
        self.regulator = settings.make()
        self.reference_n = settings.setpoint.reference_n
        self._stamps_ns = stamps_ns
        self._requested: list[float] = []
        self._applied: list[float] = []

    def step(self, board: Board) -> None:
        """The override of this tick from its force; the interpolator asks for it at the next tick."""
        sample = self.regulator.step(board.dt_s, board.cutting_force_n, self.reference_n)
        self._requested.append(sample.requested_ratio)
        self._applied.append(sample.applied_ratio)
        board.feed_override_request = sample.applied_ratio

    def finish(self) -> None:
        """Nothing to do after the run."""

    def series(self) -> dict[str, Any]:
        """``feed_override``: requested and applied ratio per tick."""
        n = len(self._applied)
        return {"feed_override": FeedOverrideSeries(self._stamps_ns[:n], np.array(self._requested, float),
                                                    np.array(self._applied, float))}
