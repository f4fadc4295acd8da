"""The physical floors of paper 004's scenario, computed from the model (what no feedback can beat).

The chain override -> τ_s -> τ_c is linear with a non-negative impulse
response, so with any feed >= 0 the force after a depth step is at least the
force with the feed cut to zero at the step (``sim.feed_stop_response``):
its peak is the overshoot floor, its return into the band the fastest
settling. A feedback law sees the step only in the force, so it cuts the feed
at its first update after the step at the earliest: the floor with the cut one
update period late is the feedback floor on a sampled loop. The steady levels
of the switch follow from ``F = K_s d f_prog r``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnc_contour_control.force import QuantiserConfig, TurningModelConfig
from cnc_tools.reproductions.paper004.sim import feed_stop_response


@dataclass(frozen=True)
class StepFloor:
    """The floor of one depth step (steady at the reference before it)."""

    depths_mm: tuple[float, float]
    overshoot_pct: float
    peak_s: float
    settling_s: float


def step_floor(model: TurningModelConfig, depths_mm: tuple[float, float], reference_n: float,
               band_fraction: float, delay_s: float = 0.0) -> StepFloor:
    """Overshoot [%] and fastest settling into ±``band_fraction`` [s] of the step ``depths_mm``, the feed cut
    ``delay_s`` [s] after it."""
    t_s, force = feed_stop_response(model, depths_mm, reference_n, delay_s=delay_s)
    peak = int(np.argmax(force))
    inside = np.nonzero(force[peak:] <= reference_n * (1.0 + band_fraction))[0]
    settling = float(t_s[peak + inside[0]]) if len(inside) else float("inf")
    return StepFloor(depths_mm, 100.0 * (force[peak] / reference_n - 1.0), float(t_s[peak]), settling)


def level_forces_n(model: TurningModelConfig, depth_mm: float, switch: QuantiserConfig) -> dict[float, float]:
    """Steady force [N] at every level of the switch at ``depth_mm``."""
    count = switch.levels or 0
    first = np.ceil(switch.min_ratio / switch.step_ratio - 1e-9) if count else 0
    levels = [round((first + i) * switch.step_ratio, 10) for i in range(count)]
    return {r: model.steady_force_n(r, depth_mm) for r in levels}


def levels_in_band(model: TurningModelConfig, depth_mm: float, switch: QuantiserConfig, reference_n: float,
                   band_fraction: float) -> list[float]:
    """The switch levels whose steady force lies within ±``band_fraction`` of ``reference_n`` at ``depth_mm``."""
    return [r for r, f in level_forces_n(model, depth_mm, switch).items()
            if abs(f - reference_n) <= band_fraction * reference_n]
