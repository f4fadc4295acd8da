"""Force figures of a run that cut: per depth-of-cut segment, peak, overshoot and settling against the reference.

Segments run from one depth change to the next (the first from the run's
first sample), taken from the plant as drawn (``summary["plant"]["cutting"]
["depth_schedule"]``; the whole run is one segment without it). Per segment,
on the recorded ``cutting_force`` (``force.x``, F_c [N]):

- peak [N] and overshoot [%] = 100 (peak / F_ref − 1), from every sample of the
  segment (a segment of one sample is a row: every sample is in exactly one);
- step overshoot [%]: the same over the segment's first ``STEP_WINDOW_S``, the
  step's transient (a steady cycle between two override levels can hold a
  level whose force lies above the reference: the segment's peak is then the
  cycle's, not the step's);
- settling [s]: from the segment's start to the last sample outside
  ±``band_fraction`` F_ref (None: still outside at the segment's end);
- over the segment's last third: mean [N], ripple (peak to peak) [N] and
  the applied override's changes per second (``feed_override``).

Without a reference (``reference_n`` None) the overshoot and settling are left
out. The paper-004 bench measures its reduced-model traces the same way
(``reproductions/paper004/metrics.py``, with a lead window for the preview).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from cnc_tools.run_record import RunRecord

#: Settling band as a fraction of the reference (paper 004's ε).
BAND_FRACTION = 0.05
#: The transient of a depth step [s]: issue 12's settling goal.
STEP_WINDOW_S = 0.5


@dataclass(frozen=True)
class ForceSegment:
    """The figures of one depth segment (forces in N, times in s, overshoot in %)."""

    start_s: float
    depth_mm: float | None
    peak_n: float
    overshoot_pct: float | None
    step_overshoot_pct: float | None
    settling_s: float | None
    mean_n: float
    ripple_n: float
    switchings_per_s: float


@dataclass(frozen=True)
class ForceFigures:
    """The force figures of a run (module docstring)."""

    reference_n: float | None
    band_fraction: float
    segments: tuple[ForceSegment, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain data (keys carry their unit)."""
        return {"reference_n": self.reference_n, "band_fraction": self.band_fraction,
                "segments": [asdict(s) for s in self.segments]}

    def lines(self) -> list[str]:
        """A short table for a terminal."""
        ref = "no reference" if self.reference_n is None else f"F_ref {self.reference_n:g} N"
        rows = [f"cutting force ({ref}, settling band ±{100 * self.band_fraction:g} %)",
                "  from s  depth mm  peak N  overshoot %  step %  settling s  mean N  ripple N  switchings/s"]
        for s in self.segments:
            rows.append(f"  {s.start_s:6.2f}  {_text(s.depth_mm, '8.2f')}  {s.peak_n:6.1f}  "
                        f"{_text(s.overshoot_pct, '11.1f')}  {_text(s.step_overshoot_pct, '6.1f')}  "
                        f"{_text(s.settling_s, '10.3f')}  {s.mean_n:6.1f}  "
                        f"{s.ripple_n:8.1f}  {s.switchings_per_s:12.1f}")
        return rows


def _text(value: float | None, spec: str) -> str:
    width = int(spec.split(".")[0])
    return "-".rjust(width) if value is None else format(value, spec)


def _schedule(run: RunRecord) -> list[tuple[float, float | None]]:
    """(start_s, depth_mm) of each depth change of the plant as drawn; one segment from 0 without it."""
    plant = run.summary.get("plant", {})
    cutting = plant.get("cutting", {}) if isinstance(plant, Mapping) else {}
    rows = cutting.get("depth_schedule") or [[0.0, None]]
    return [(float(t), None if d is None else float(d)) for t, d in rows]


def _settling_s(t_s: np.ndarray, force_n: np.ndarray, start_s: float, reference_n: float,
                band: float) -> float | None:
    outside = np.abs(force_n - reference_n) > band * reference_n
    if not outside.any():
        return 0.0
    return None if outside[-1] else max(0.0, float(t_s[np.nonzero(outside)[0][-1]]) - start_s)


def _segment(run: RunRecord, window: np.ndarray, start_s: float, depth_mm: float | None,
             reference_n: float | None, band: float) -> ForceSegment:
    assert run.cutting_force is not None
    t_s, force_n = run.cutting_force.stamp_ns * 1e-9, run.cutting_force.force_n[:, 0]
    t, f = t_s[window], force_n[window]
    steady = t >= t[0] + 2.0 * (t[-1] - t[0]) / 3.0
    changes = 0.0
    if run.feed_override is not None and run.feed_override.applied_ratio.size == t_s.size and t[-1] > t[0]:
        applied = run.feed_override.applied_ratio[window][steady]
        changes = np.count_nonzero(np.diff(applied)) / max(float(t[steady][-1] - t[steady][0]), 1e-9)
    peak, step_peak = float(f.max()), float(f[t < t[0] + STEP_WINDOW_S].max())
    return ForceSegment(start_s, depth_mm, peak, None if reference_n is None else 100.0 * (peak / reference_n - 1.0),
                        None if reference_n is None else 100.0 * (step_peak / reference_n - 1.0),
                        None if reference_n is None else _settling_s(t, f, start_s, reference_n, band),
                        float(f[steady].mean()), float(np.ptp(f[steady])), float(changes))


def force_figures(run: RunRecord, reference_n: float | None = None,
                  band_fraction: float = BAND_FRACTION) -> ForceFigures | None:
    """The figures of ``run`` (None when it recorded no cutting force)."""
    if run.cutting_force is None or run.cutting_force.stamp_ns.size < 2:
        return None
    t_s = run.cutting_force.stamp_ns * 1e-9
    schedule = [(s, d) for s, d in _schedule(run) if s <= t_s[-1]] or [(0.0, None)]
    schedule[0] = (min(schedule[0][0], float(t_s[0])), schedule[0][1])
    ends = [s for s, _ in schedule[1:]] + [np.inf]
    segments = []
    for (start_s, depth_mm), end_s in zip(schedule, ends):
        window = (t_s >= start_s) & (t_s < end_s)
        if np.count_nonzero(window) >= 1:
            segments.append(_segment(run, window, start_s, depth_mm, reference_n, band_fraction))
    return ForceFigures(reference_n, band_fraction, tuple(segments))
