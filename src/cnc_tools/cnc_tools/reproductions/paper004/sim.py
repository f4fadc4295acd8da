"""The closed loop of paper 004's Fig. 3, sample by sample: regulator -> switch -> interpolator lag -> cutting.

Per sample of ``dt_s``: the applied override ratio r gives the commanded feed
``v_c = r f_prog N`` [mm/min]; the interpolator's lag τ_s (Eq. 1) gives the
feed-axis velocity; :class:`cnc_plant_sim.process.turning.TurningProcess` gives the
measured force; the :class:`~cnc_contour_control.force.ForceRegulator` reads
it and sets the ratio for the next sample. :func:`simulate` returns the
traces; :func:`feed_stop_response` is the same chain with the feed command
cut to zero (the floors of :mod:`.floors`).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.units import MM_MIN_PER_M_S
from cnc_contour_control.force import FirstOrderLag, ForceRegulator, TurningModelConfig
from cnc_plant_sim.process.turning import TurningConfig, TurningProcess


@dataclass(frozen=True)
class Traces:
    """One closed-loop run: arrays of shape (n,) on the sample times."""

    t_s: npt.NDArray[np.float64]
    force_n: npt.NDArray[np.float64]
    requested_ratio: npt.NDArray[np.float64]
    applied_ratio: npt.NDArray[np.float64]
    depth_mm: npt.NDArray[np.float64]


@dataclass(frozen=True)
class Loop:
    """The plant side of a run: nominal model, process, sample time, duration, the start."""

    model: TurningModelConfig
    process: TurningConfig
    dt_s: float = 1.0e-3
    duration_s: float = 12.0
    from_rest: bool = False


def _start(loop: Loop, regulator: ForceRegulator, reference_n: float) -> tuple[TurningProcess, FirstOrderLag]:
    """Steady cutting at the continuous ratio for the reference (or at rest), regulator and plant alike."""
    process = TurningProcess(loop.process)
    depth = process.depth_mm()
    ratio = 0.0 if loop.from_rest else loop.model.steady_ratio(reference_n, depth)
    regulator.reset(ratio if not loop.from_rest else 1.0)
    applied = 0.0 if loop.from_rest else regulator.last.applied_ratio
    process.reset(loop.model.steady_force_n(applied, depth))
    return process, FirstOrderLag(loop.model.interpolator_tau_s, applied * loop.model.programmed_feed_mm_min)


def simulate(loop: Loop, regulator: ForceRegulator, reference_n: float) -> Traces:
    """Run ``regulator`` on the loop for ``loop.duration_s`` at the constant ``reference_n`` [N]."""
    process, interpolator = _start(loop, regulator, reference_n)
    n = int(round(loop.duration_s / loop.dt_s))
    out = np.empty((5, n))
    applied = regulator.last.applied_ratio if not loop.from_rest else 0.0
    feed_mm_min = loop.model.programmed_feed_mm_min
    for k in range(n):
        depth = process.depth_mm()
        velocity_m_s = interpolator.step(loop.dt_s, applied * feed_mm_min) / MM_MIN_PER_M_S
        force = process.step(velocity_m_s, loop.dt_s)
        sample = regulator.step(loop.dt_s, force, reference_n)
        applied = sample.applied_ratio
        out[:, k] = (process.t_s, force, sample.requested_ratio, applied, depth)
    return Traces(*out)


def feed_stop_response(model: TurningModelConfig, depths_mm: Sequence[float], reference_n: float,
                       dt_s: float = 1.0e-4, duration_s: float = 1.0,
                       delay_s: float = 0.0) -> tuple[npt.NDArray[np.float64], ...]:
    """Steady at ``reference_n`` at depth ``depths_mm[0]``; at t = 0 the depth steps to ``depths_mm[1]``, and at
    ``delay_s`` [s] v_c to 0.

    Returns ``(t_s, force_n)``, shape (n,): the lowest force any feed >= 0 from ``delay_s`` on can give after
    the step (the chain is linear with a non-negative impulse response).
    """
    before, after = depths_mm
    ratio = model.steady_ratio(reference_n, before)
    process = TurningProcess(TurningConfig(specific_force_n_mm2=model.specific_force_n_mm2,
                                           spindle_rpm=model.spindle_rpm, depth_schedule=((0.0, after),)))
    process.reset(reference_n)
    interpolator = FirstOrderLag(model.interpolator_tau_s, ratio * model.programmed_feed_mm_min)
    n = int(round(duration_s / dt_s))
    force = np.empty(n)
    held_mm_min = ratio * model.programmed_feed_mm_min
    for k in range(n):
        command = held_mm_min if k * dt_s < delay_s - 1e-12 else 0.0
        force[k] = process.step(interpolator.step(dt_s, command) / MM_MIN_PER_M_S, dt_s)
    return dt_s * np.arange(1, n + 1, dtype=np.float64), force

