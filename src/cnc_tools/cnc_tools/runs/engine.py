"""The in-process engine: the node graph's core objects in the same tick order, without DDS.

Tick k (stamp t_k = k·T, integer nanoseconds as on the wire):
1. the plant's state at t_k (what ``joint_states(k)`` carries);
2. the interpolator's reference at t_k;
3. (estimator, compensator: later stages);
4. each servo's command from the reference and the measured position, with
   dt from the stamps (as the servo node computes it);
5. the plant integrates over T with every axis's command.
A lockstep node-graph run of the same scenario gives the same trajectories.

Speed: the reference is open-loop (it depends on the stamp only), so it is
computed for all ticks at once with :meth:`Interpolator.sample_array`, which
agrees with the node's per-tick :meth:`Interpolator.sample` to 1e-12 m (a few
ulp on arcs; ``test_bench`` checks it). The commands are quantised, so the
positions and commands are the node graph's exactly unless a command lands
within ~1e-10 drive units of a rounding boundary. The tick loop reads the axes'
state as floats and collects rows in Python lists, converted to arrays once.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cnc_contour_control.interpolation import ReferenceTrajectory
from cnc_contour_control.lockstep import NS_PER_S, duration_to_ns, seconds_to_ns
from cnc_contour_control.servo import ServoController
from cnc_plant_sim.plant import Plant, make_plant
from cnc_tools.runs.scenario import Scenario

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


def tick_stamps_s(n_ticks: int, sample_ns: int) -> FloatArray:
    """Stamps ``k·T`` of ticks 0..n_ticks-1 as seconds, shape (n_ticks,).

    Converted as :func:`~cnc_contour_control.lockstep.ns_to_s` converts each
    integer-nanosecond stamp on the wire (the interpolator node samples there).
    """
    return (np.arange(n_ticks, dtype=np.int64) * sample_ns) * 1e-9


def run_engine(scenario: Scenario, clock: Callable[[], float] | None = None) -> EngineResult:
    """Simulate ``scenario`` in-process; ``clock`` (wall seconds) only times the run."""
    import time

    wall = clock or time.perf_counter
    plant = make_plant(scenario.plant)
    interpolator = scenario.make_interpolator()
    servos = [ServoController(config) for config in scenario.servos]
    plant.reset(list(scenario.program.start_m))
    n_ticks = tick_count(scenario)
    sample_ns = seconds_to_ns(scenario.sample_time_s)
    started = wall()
    reference = interpolator.sample_array(tick_stamps_s(n_ticks, sample_ns))
    rows = _tick_loop(plant, servos, reference, sample_ns / NS_PER_S, scenario.sample_time_s)
    position, velocity, command = (np.array(r, dtype=float).reshape(n_ticks, len(scenario.axes)) for r in rows)
    return EngineResult(
        axes=scenario.axes,
        time_s=np.arange(n_ticks) * (sample_ns / NS_PER_S),
        position_m=position, velocity_m_s=velocity,
        reference_m=reference.position_m, command=command,
        wall_time_s=wall() - started,
    )


def _tick_loop(plant: Plant, servos: list[ServoController], reference: ReferenceTrajectory,
               servo_dt_s: float, plant_dt_s: float) -> tuple[list[list[float]], ...]:
    """Ticks 0..M-1 in the node graph's order; rows (M,) of (n_axes,) positions, velocities, commands.

    ``servo_dt_s`` is the period the servo node computes from the stamps,
    ``plant_dt_s`` the sample time the plant node integrates over.
    """
    axes, commands_of = plant.axes, [servo.command for servo in servos]
    ref_rows = zip(reference.position_m.tolist(), reference.velocity_m_s.tolist(),
                   reference.acceleration_m_s2.tolist())
    positions: list[list[float]] = []
    velocities: list[list[float]] = []
    commands: list[list[float]] = []
    step = plant.step
    for ref_p, ref_v, ref_a in ref_rows:
        pos = [axis.position_m for axis in axes]
        velocities.append([axis.velocity_m_s for axis in axes])
        cmd = [command(servo_dt_s, r, v, a, x) for command, r, v, a, x in zip(commands_of, ref_p, ref_v, ref_a, pos)]
        step(cmd, plant_dt_s)
        positions.append(pos)
        commands.append(cmd)
    return positions, velocities, commands
