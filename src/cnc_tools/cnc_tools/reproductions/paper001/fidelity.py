"""Estimator fidelity (paper 001, Section 2.1): every estimator against the scorer's exact contour error.

For each contour of :data:`CONTOURS` the in-process engine runs the scenario
(closed loop, T = 1 ms); each estimator of
:data:`~cnc_contour_control.estimators.ESTIMATORS` is then stepped over the
recorded (reference, position) pairs in tick order, as the estimator stage
steps it. The exact value is the scorer's (``contour_error_series``:
``Program.contour_distance``, unsigned) with the sign of
:func:`~cnc_contour_control.estimators.signed_contour_error` (the same
nearest point; positive left of travel), so signed estimates are compared
with a signed truth.

Samples are split in two sets. **Following**: the actual position lags the
newest reference (its offset from the reference points against the last
direction of reference motion), the situation paper 001's model assumes
("P(t) is always delayed from P*(t)", Fig. 1). **Ahead**: the actual has
reached or passed the newest reference, as when the PID's integral carries
the axes past a decelerating reference at the program's end or before an
exact stop, and on paper 001's own loop in most moving samples; no reference
point lies ahead of the position then, and the window estimator continues
the circle through its three newest points, so it stays exact while the
program goes on, but past an open program's end (or an exact stop's vertex)
the exact error is the distance to that point, which no estimator built on
past references sees. The goals (:data:`GOAL_MAX_UM`, :data:`GOAL_RMS_UM`, :data:`GOAL_STEPS`) are
judged on the following samples of the smooth contours; corners and the
ahead samples are reported with their worst case and where it happens. Window steps
are counted in steady state: the reference at a constant feed for the last
:data:`STEADY_TICKS` ticks.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.units import M_PER_UM
from cnc_contour_control.estimators import ContourEstimator, make_estimator, signed_contour_error
from cnc_tools.analysis.scoring import contour_error_series
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import Scenario, load_scenario

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: Goals on smooth contours at 1 kHz (issue 8): max and RMS |estimate − exact| [µm], window steps per sample.
GOAL_MAX_UM, GOAL_RMS_UM, GOAL_STEPS = 1.0, 0.1, 5
#: Ticks of constant reference feed before a sample counts as steady state.
STEADY_TICKS = 100
#: Feed changes below this are "constant" [m/s].
FEED_TOLERANCE_M_S = 1e-9


@dataclass(frozen=True)
class Contour:
    """One contour of the fidelity bench: a scenario file (relative to the project root) and top-level overrides."""

    name: str
    scenario: str
    smooth: bool
    note: str
    overrides: Mapping[str, Any] = field(default_factory=dict)

    def load(self, root: Path) -> Scenario:
        """The validated scenario."""
        return load_scenario(root / self.scenario, dict(self.overrides))


#: The contours: paper 001's line and circle, paper 000's corner, an involute of arcs, a 3-axis helix.
CONTOURS: tuple[Contour, ...] = (
    Contour("line", "scenarios/fidelity/line.yaml", True, "45°, 30 mm, 2.7 m/min (paper 001 Table 2)"),
    Contour("circle", "scenarios/fidelity/circle.yaml", True, "r = 10 mm, 5 m/min (paper 001 Table 3)"),
    Contour("corner", "scenarios/paper000_corner_high.yaml", False,
            "paper 000 corner, 90°, 0.6 m/min, 8-bit DAC, at T = 1 ms", {"sample_time_s": 0.001}),
    Contour("involute", "scenarios/fidelity/involute.yaml", True,
            "involute of r = 2 mm, 148 tangent arcs, 3 m/min"),
    Contour("helix", "scenarios/fidelity/helix.yaml", True, "3 axes, r = 10 mm, 2 turns of 2 mm, 3 m/min"),
)


def get_contour(name: str) -> Contour:
    """The contour called ``name``; an unknown name lists the valid ones."""
    found = {c.name: c for c in CONTOURS}
    if name not in found:
        raise ConfigError(f"contour must be one of {sorted(found)}, got {name!r}")
    return found[name]


# =========================================================================== the exact error
@dataclass(frozen=True, eq=False)
class Exact:
    """The exact signed contour error of a run's samples and where they lie (all arrays (N,))."""

    error_m: FloatArray
    time_s: FloatArray
    path_length_m: FloatArray
    junction_m: FloatArray
    following: BoolArray
    steady: BoolArray


def exact_of(record: RunRecord, plane: tuple[int, int] = (0, 1)) -> Exact:
    """The scorer's exact contour error of every sample, signed, with the following and steady-state masks.

    ``junction_m`` is the distance along the path from the nearest point to
    the nearest segment junction or program end (inf for a closed single segment).
    """
    reference = record.reference
    if reference is None or not np.array_equal(reference.stamp_ns, record.joint_states.stamp_ns):
        raise ConfigError(f"run {record.name!r}: the fidelity needs a reference at every joint_states stamp")
    series, window = contour_error_series(record)
    if window.n_scored != record.ticks:
        raise ConfigError(f"run {record.name!r}: {record.ticks - window.n_scored} samples were not scored "
                          f"({window.describe()})")
    signed, _, _ = signed_contour_error(record.program, series.position_m, plane)
    following = following_mask(reference.position_m, series.position_m)
    moving = ~reference.done.astype(bool)
    return Exact(np.copysign(series.error_m, signed), series.time_s, series.path_length_m,
                 _junction_distance_m(record, series.path_length_m), following,
                 steady_mask(reference.feed_m_s, moving) & following)


def following_mask(reference_m: FloatArray, position_m: FloatArray) -> BoolArray:
    """Samples (N,) whose position lags the reference: ``(P − R)·d < 0``, d the last reference step.

    ``d`` is the last non-zero step of the reference up to the sample (held
    while the reference stands still); samples before the reference first
    moves count as following (position and reference coincide there).
    """
    steps = np.diff(reference_m, axis=0, prepend=reference_m[:1])
    moved = np.linalg.norm(steps, axis=1) > 0.0
    last = np.maximum.accumulate(np.where(moved, np.arange(moved.size), -1))
    direction = np.where((last >= 0)[:, None], steps[np.maximum(last, 0)], 0.0)
    return (np.einsum("ij,ij->i", position_m - reference_m, direction) < 0.0) | (last < 0)


def _junction_distance_m(record: RunRecord, path_length_m: FloatArray) -> FloatArray:
    program = record.program
    marks = list(program.segment_start_m[1:])
    closed = float(np.linalg.norm(program.end_m - program.start_m)) < 1e-9
    if not closed:
        marks += [0.0, program.total_length_m]
    if not marks:
        return np.full(path_length_m.size, np.inf)
    return np.min(np.abs(path_length_m[:, None] - np.asarray(marks)[None, :]), axis=1)


def steady_mask(feed_m_s: FloatArray, moving: BoolArray, ticks: int = STEADY_TICKS) -> BoolArray:
    """Samples whose reference feed is > 0 and has been constant for the last ``ticks`` ticks."""
    feed = np.asarray(feed_m_s, dtype=float)
    steady = np.zeros(feed.size, dtype=bool)
    if feed.size <= ticks:
        return steady
    windows = np.lib.stride_tricks.sliding_window_view(feed, ticks + 1)
    constant = (windows.max(axis=1) - windows.min(axis=1)) <= FEED_TOLERANCE_M_S
    steady[ticks:] = constant & (feed[ticks:] > 0.0)
    return steady & moving


# =========================================================================== estimators over a run
@dataclass(frozen=True, eq=False)
class Trace:
    """An estimator stepped over a run: signed estimates (N,) m, window steps (N,), distances computed (N,)."""

    error_m: FloatArray
    steps: IntArray
    window: IntArray


def trace(estimator: ContourEstimator, reference_m: FloatArray, position_m: FloatArray) -> Trace:
    """Step ``estimator`` over (reference, position) pairs (N, n) in order, as the estimator stage does."""
    estimator.reset()
    errors, steps, window = [], [], []
    for ref, pos in zip(reference_m.tolist(), position_m.tolist()):
        estimate = estimator.step(ref, pos)
        errors.append(estimate.contour_error_m)
        steps.append(estimate.steps)
        window.append(estimate.window_size)
    return Trace(np.array(errors), np.array(steps, dtype=np.int64), np.array(window, dtype=np.int64))


@dataclass(frozen=True)
class Worst:
    """The largest |estimate − exact| of a window and where: time [s], path position and junction distance [mm]."""

    error_um: float
    time_s: float
    path_mm: float
    junction_mm: float

    @classmethod
    def of(cls, difference_m: FloatArray, exact: Exact, mask: BoolArray) -> Worst:
        rows = np.flatnonzero(mask)
        if rows.size == 0:
            return cls(math.nan, math.nan, math.nan, math.nan)
        k = rows[int(np.argmax(np.abs(difference_m[rows])))]
        return cls(abs(float(difference_m[k])) / M_PER_UM, float(exact.time_s[k]), float(exact.path_length_m[k]) * 1e3,
                   float(exact.junction_m[k]) * 1e3)


@dataclass(frozen=True)
class FidelityRow:
    """One contour and estimator: errors [µm] on the following samples, the worst ahead, steps in steady state.

    ``max_um``, ``rms_um``: of the signed difference estimate − exact;
    ``magnitude_max_um``: of ``|estimate| − |exact|`` (at a vertex the sign of
    the exact error is the first segment's, the tie rule of the scorer, while an
    estimator may measure against the next one: the magnitudes still agree).
    """

    contour: str
    estimator: str
    smooth: bool
    samples: int
    contour_max_um: float
    max_um: float
    rms_um: float
    magnitude_max_um: float
    worst: Worst
    ahead_samples: int
    ahead: Worst
    steady_samples: int
    steps_mean: float
    steps_max: int
    window_mean: float
    window_max: int

    @property
    def goals_met(self) -> bool | None:
        """Whether the smooth-contour goals hold (None for a contour with corners: reported, not judged)."""
        if not self.smooth:
            return None
        return self.max_um <= GOAL_MAX_UM and self.rms_um <= GOAL_RMS_UM and self.steps_max <= GOAL_STEPS


def fidelity_row(contour: Contour, name: str, exact: Exact, found: Trace) -> FidelityRow:
    """Compare one estimator's trace with the exact error of the run."""
    difference = found.error_m - exact.error_m
    following, steady = exact.following, exact.steady
    lagging = np.abs(difference[following])
    return FidelityRow(
        contour=contour.name, estimator=name, smooth=contour.smooth, samples=int(following.sum()),
        contour_max_um=float(np.max(np.abs(exact.error_m[following]))) / M_PER_UM,
        max_um=float(lagging.max()) / M_PER_UM, rms_um=float(np.sqrt(np.mean(lagging ** 2))) / M_PER_UM,
        magnitude_max_um=float(np.max(np.abs(np.abs(found.error_m) - np.abs(exact.error_m))[following])) / M_PER_UM,
        worst=Worst.of(difference, exact, following), ahead_samples=int((~following).sum()),
        ahead=Worst.of(difference, exact, ~following),
        steady_samples=int(steady.sum()),
        steps_mean=float(found.steps[steady].mean()) if steady.any() else math.nan,
        steps_max=int(found.steps[steady].max()) if steady.any() else 0,
        window_mean=float(found.window[steady].mean()) if steady.any() else math.nan,
        window_max=int(found.window[steady].max()) if steady.any() else 0)


def run_contour(contour: Contour, root: Path) -> RunRecord:
    """The engine's record of the contour's scenario."""
    return run_engine(contour.load(root))


def measure(contour: Contour, record: RunRecord, names: Sequence[str],
            params: Mapping[str, Mapping[str, Any]] | None = None) -> list[FidelityRow]:
    """One row per estimator ``names`` on ``record`` (params per estimator name, default the config defaults)."""
    exact = exact_of(record)
    reference, position = record.reference.position_m, record.joint_states.position_m  # type: ignore[union-attr]  # engine runs have both
    rows = []
    for name in names:
        estimator = make_estimator(name, (params or {}).get(name, {}), record.program)
        rows.append(fidelity_row(contour, name, exact, trace(estimator, reference, position)))
    return rows


# =========================================================================== the involute program
def involute_program(base_radius_mm: float = 2.0, start_rad: float = 2.0, end_rad: float = 3.0 * math.pi,
                     step_rad: float = 0.05, feed_mm_min: float = 3000.0) -> dict[str, Any]:
    """A scenario ``program:`` section: the involute of a circle as tangent-continuous arcs (mm).

    The involute of radius ``a`` has tangent direction ``t`` and radius of
    curvature ``a t`` at parameter ``t``. Arc ``i`` turns the tangent from
    ``t_i`` to ``t_i + Δt`` counter-clockwise with radius ``a (t_i + Δt/2)``, so
    junctions are tangent-continuous (no exact stop) and the curve follows the
    involute to O(Δt²). Start at the involute point of ``start_rad``.
    """
    count = max(1, int(round((end_rad - start_rad) / step_rad)))
    step = (end_rad - start_rad) / count
    a, t = base_radius_mm, start_rad
    point = np.array([a * (math.cos(t) + t * math.sin(t)), a * (math.sin(t) - t * math.cos(t))])
    segments = []
    for i in range(count):
        t0 = start_rad + i * step
        radius = a * (t0 + step / 2.0)
        center = point + radius * np.array([-math.sin(t0), math.cos(t0)])
        end = center + radius * np.array([math.sin(t0 + step), -math.cos(t0 + step)])
        segments.append({"arc": {"to_mm": [round(float(v), 12) for v in end],
                                 "center_mm": [round(float(v), 12) for v in center], "direction": "ccw"}})
        point = np.array(segments[-1]["arc"]["to_mm"])
    start = [a * (math.cos(t) + t * math.sin(t)), a * (math.sin(t) - t * math.cos(t))]
    return {"axes": ["x", "y"], "start_mm": [round(v, 12) for v in start], "feed_mm_min": feed_mm_min,
            "segments": segments}
