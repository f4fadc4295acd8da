"""Run parameters of the plant node: start, sample time, duration, time mode, summary, timeouts (ROS-free).

The plant node declares these beside its :class:`~cnc_plant_sim.models.plant.PlantConfig`
(see :mod:`cnc_contour_control.graph.stage_params` for the other stages' run parameters).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from cnc_contour_control.core.config import require_choice
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.graph.stage_params import SAMPLE_TIME_RANGE_S, TIMEOUT_RANGE_S, require_startup_after
from cnc_plant_sim.run.watchdog import WatchdogParams

#: Time modes of the plant: lockstep (the plant waits for every command) or real time (a wall timer).
MODES = ("lockstep", "realtime")


@dataclass(frozen=True)
class PlantRunParams(WatchdogParams):
    """Run parameters of the plant node (with the real-time command watchdog's, :mod:`cnc_plant_sim.run.watchdog`)."""

    initial_position_m: tuple[float, ...] = param((0.0,), unit="m", read_only=True,
                                                  description="initial axis positions, one per axis "
                                                              "(or one for every axis)")
    sample_time_s: float = param(0.01, unit="s", low=SAMPLE_TIME_RANGE_S[0], high=SAMPLE_TIME_RANGE_S[1],
                                 read_only=True, description="sample time T")
    duration_s: float = param(10.0, unit="s", low=1.0e-3, high=1.0e6, read_only=True,
                              description="simulated duration of the run")
    mode: str = param("lockstep", read_only=True, description=f"time mode, one of {list(MODES)}")
    summary_file: str = param("", read_only=True, description="write the run summary here as JSON (empty: none)")
    command_timeout_s: float = param(5.0, unit="s", low=TIMEOUT_RANGE_S[0], high=TIMEOUT_RANGE_S[1],
                                     read_only=True, description="wall time a tick may wait for its commands")
    startup_timeout_s: float = param(90.0, unit="s", low=TIMEOUT_RANGE_S[0], high=TIMEOUT_RANGE_S[1],
                                     read_only=True,
                                     description="wall time the first tick may wait (graph discovery), "
                                                 ">= command_timeout_s")

    def __post_init__(self) -> None:
        object.__setattr__(self, "initial_position_m", _positions(self.initial_position_m))
        require_choice("mode", self.mode, MODES)
        if not isinstance(self.summary_file, str):
            raise ConfigError(f"summary_file must be a path, got {self.summary_file!r}")
        check_ranges(self)
        require_startup_after(self.command_timeout_s, self.startup_timeout_s, "command_timeout_s")

    def positions_m(self, n_axes: int) -> list[float]:
        """The initial positions of ``n_axes`` axes [m] (one value given: every axis)."""
        values = list(self.initial_position_m)
        if len(values) == 1:
            return values * n_axes
        if len(values) != n_axes:
            raise ConfigError(f"initial_position_m needs 1 or {n_axes} values, got {len(values)}")
        return values


def _positions(values: object) -> tuple[float, ...]:
    if isinstance(values, str) or not isinstance(values, Sequence) or not values:
        raise ConfigError(f"initial_position_m must be a non-empty list of numbers, got {values!r}")
    out = []
    for i, value in enumerate(values):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ConfigError(f"initial_position_m[{i}] must be a finite number, got {value!r}")
        out.append(float(value))
    return tuple(out)
