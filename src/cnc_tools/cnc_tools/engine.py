"""The in-process engine: the node graph's core objects in the same tick order, without DDS.

Tick k (stamp t_k = k·T, integer nanoseconds as on the wire):
1. the plant's state at t_k (what ``joint_states(k)`` carries);
2. the interpolator's reference at t_k;
3. (estimator, compensator: later stages);
4. each servo's command from the reference and the measured position, with
   dt from the stamps (as the servo node computes it);
5. the plant integrates over T with every axis's command.
A lockstep node-graph run of the same scenario gives the same trajectories.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cnc_contour_control.lockstep import NS_PER_S, duration_to_ns, ns_to_s, seconds_to_ns
from cnc_contour_control.servo import ServoController
from cnc_plant_sim.plant import make_plant
from cnc_tools.scenario import Scenario

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class EngineResult:
    """Trajectories of one run; arrays are (n_ticks,) or (n_ticks, n_axes), SI units.

    Row k holds tick k: the joint state published at t_k, the reference at
    t_k, and the command answering it.
    """

    axes: tuple[str, ...]
    time_s: FloatArray
    position_m: FloatArray
    velocity_m_s: FloatArray
    reference_m: FloatArray
    command: FloatArray
    wall_time_s: float

    @property
    def ticks(self) -> int:
        """Number of ticks simulated."""
        return int(self.time_s.size)

    @property
    def real_time_factor(self) -> float:
        """Simulated time per wall time."""
        return float(self.time_s[-1] + (self.time_s[1] - self.time_s[0])) / self.wall_time_s if self.ticks > 1 else float("nan")


def tick_count(scenario: Scenario) -> int:
    """Ticks of a run: stamps 0, T, ... up to and including the duration."""
    return duration_to_ns(scenario.duration_s) // seconds_to_ns(scenario.sample_time_s) + 1


def run_engine(scenario: Scenario, clock: Callable[[], float] | None = None) -> EngineResult:
    """Simulate ``scenario`` in-process; ``clock`` (wall seconds) only times the run."""
    import time

    wall = clock or time.perf_counter
    plant = make_plant(scenario.plant)
    interpolator = scenario.make_interpolator()
    servos = [ServoController(config) for config in scenario.servos]
    plant.reset(list(scenario.program.start_m))
    n_ticks, n_axes = tick_count(scenario), len(scenario.axes)
    sample_ns = seconds_to_ns(scenario.sample_time_s)
    out = {key: np.empty((n_ticks, n_axes)) for key in ("position", "velocity", "reference", "command")}
    started = wall()
    for k in range(n_ticks):
        positions, velocities = plant.positions_m(), plant.velocities_m_s()
        sample = interpolator.sample(ns_to_s(k * sample_ns))
        commands = [
            servo.step(sample_ns / NS_PER_S, float(sample.position_m[i]), float(sample.velocity_m_s[i]),
                       float(sample.acceleration_m_s2[i]), float(positions[i])).command
            for i, servo in enumerate(servos)
        ]
        plant.step(commands, scenario.sample_time_s)
        out["position"][k], out["velocity"][k] = positions, velocities
        out["reference"][k], out["command"][k] = sample.position_m, commands
    return EngineResult(
        axes=scenario.axes,
        time_s=np.arange(n_ticks) * (sample_ns / NS_PER_S),
        position_m=out["position"], velocity_m_s=out["velocity"],
        reference_m=out["reference"], command=out["command"],
        wall_time_s=wall() - started,
    )
