"""The bench's measures of one force trace: per depth segment overshoot, settling, ripple, offset, switchings.

A segment runs from a depth step to the next (the first from 0). Its
transient window opens ``lead_s`` before the step (a preview acts there) and
closes ``lead_s`` before the next one (the last at the run's end); its steady part is the window's last
``steady_s``. Settling: the last time outside ±band before the steady part
ends, from the step (None: still outside at the end). Switchings: changes of
the applied ratio per second. The step overshoot is the overshoot up to
``step_s`` after the step (the step's transient, as the floors measure it; at
a depth where no override level lands, a steady cycle slow enough to change
the override rarely holds the level above the reference long enough to reach
its force, and the window's peak is then the cycle's).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnc_contour_control.force import DepthSchedule
from cnc_tools.reproductions.paper004.sim import Traces


@dataclass(frozen=True)
class Segment:
    """The measures of one depth segment (forces in N, times in s)."""

    step_s: float
    depth_mm: float
    before_n: float
    overshoot_pct: float
    step_overshoot_pct: float
    undershoot_pct: float
    settling_s: float | None
    ripple_n: float
    mean_n: float
    switchings_per_s: float


def _settling(t_s: np.ndarray, force_n: np.ndarray, step_s: float, reference_n: float, band: float) -> float | None:
    outside = np.abs(force_n - reference_n) > band * reference_n
    if not outside.any():
        return 0.0
    if outside[-1]:
        return None
    return max(0.0, float(t_s[np.nonzero(outside)[0][-1]]) - step_s)


def segment(traces: Traces, step_s: float, next_s: float, depth_mm: float, reference_n: float, band: float,
            lead_s: float = 0.5, steady_s: float = 1.5, transient_s: float = 0.5) -> Segment:
    """The measures of the segment [step_s, next_s) at ``depth_mm`` (module docstring; the run's end: no lead)."""
    t, f = traces.t_s, traces.force_n
    close_s = next_s if next_s > t[-1] else next_s - lead_s
    window = (t > step_s - lead_s) & (t <= close_s) if step_s > 0.0 else (t <= close_s)
    steady = window & (t > close_s - steady_s)
    before = float(f[np.searchsorted(t, step_s) - 1]) if step_s > 0.0 else float(f[0])
    changes = np.count_nonzero(np.diff(traces.applied_ratio[steady]))
    transient = window & (t < step_s + transient_s)
    return Segment(step_s, depth_mm, before, 100.0 * (float(f[window].max()) / reference_n - 1.0),
                   100.0 * (float(f[transient].max()) / reference_n - 1.0),
                   100.0 * (float(f[window].min()) / reference_n - 1.0),
                   _settling(t[window], f[window], step_s, reference_n, band), float(np.ptp(f[steady])),
                   float(f[steady].mean()), int(changes) / steady_s)


def segments(traces: Traces, schedule: DepthSchedule, reference_n: float, band: float) -> list[Segment]:
    """Every segment of a run on ``schedule`` (its steps within the run)."""
    end_s = float(traces.t_s[-1])
    bounds = [0.0, *[t for t in schedule.step_times_s() if t < end_s], end_s + 1e-9]
    return [segment(traces, a, b, schedule.depth_mm(a), reference_n, band) for a, b in zip(bounds[:-1], bounds[1:])]


def switchings_per_s(traces: Traces) -> float:
    """Changes of the applied ratio per second over the whole run."""
    return np.count_nonzero(np.diff(traces.applied_ratio)) / float(traces.t_s[-1] - traces.t_s[0])
