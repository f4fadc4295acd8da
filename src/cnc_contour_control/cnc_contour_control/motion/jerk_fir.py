"""The FIR jerk mode (``jerk_mode: fir``): the (v, a)-limited blended plan, then a moving average per axis.

The planner plans the program as it does without a jerk limit (blends within ``P_b = (1 - s) P``,
``s`` = ``jerk_filter_tolerance_share``), and the reference is the mean of the plan at the ``n`` sample times
``t, t - T, ..., t - (n - 1) T`` (``T`` = ``jerk_filter_period_s``, ``n`` by
:func:`~cnc_contour_control.motion.jerk_filter.filter_taps`): velocity and acceleration keep the plan's limits,
the jerk keeps ``2 amax / (n T) <= jmax`` at ``T`` and at every multiple of ``T`` (a difference over a multiple
is a positive-weight average of differences over ``T``). The program ends ``(n - 1) T`` after the plan.

The average leaves the path where it curves. Two planning changes keep it within the filter's share
``P_f = s P``:

- **Curved segments** (arcs, blends) are slowed: at path speed ``v`` the ``n`` samples span ``L = v T_w``
  (``T_w = (n - 1) T``); on a circle of curvature ``κ`` at constant speed the mean lies
  ``κ v² T² (n² - 1) / 24`` inside it, so ``L <= sqrt(24 P_f / κ) T_w / (T sqrt(n² - 1))`` (an arc as
  written, not a blend, may take the whole of P). Where ``L`` would
  pass the whole curve (a short blend of turn ``θ``: the samples on two lines at a corner, whose mean lies
  ``L sin θ / 8`` off them), ``L <= max(length, 8 P_f / θ)`` as well. The bench and the property tests measure
  the deviation on every sample (:mod:`~cnc_contour_control.motion.reference_check`).
- **Stops at corners** hold still for ``T_w``: no window then holds samples of both lines while moving (a
  window across a moving corner would cut it by up to ``amax T_w² sin θ / 8``). At rest the mean is on the path.

A junction passed at speed (a turn under ``corner_angle_tolerance_deg``) turns the velocity in no time, which
the average spreads over ``T_w``: the plan's axis accelerations keep a reserve for it
(:func:`kink_acceleration_m_s2`, whole and streamed alike).

With a feed override the interpolator is planned with :func:`~cnc_contour_control.motion.feed_override.
planning_limits` (acceleration ÷ k², jerk ÷ k³), so its window ``T_w`` is ``k_max`` times the machine's: the
caps hold at every ratio up to ``k_max`` while :class:`LiveJerkFilter` filters the retimed reference tick by tick
with the machine's limits. The override's ramps keep the acceleration limit before the filter, so their jerk is
limited after it.
"""
from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.blending import BlendedProgram
from cnc_contour_control.motion.geometry import LineSegment, Program
from cnc_contour_control.motion.jerk_filter import FloatArray, MovingAverage, filter_taps, moving_average_rows
from cnc_contour_control.motion.reference_types import ReferenceSample, ReferenceTrajectory
from cnc_contour_control.motion.segment_tangents import junction_turns_rad

#: Filtered arrays: times, positions, velocities, accelerations, path lengths, segments, feeds, done.
FilteredArrays = tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.intp], FloatArray,
                       NDArray[np.bool_]]

#: Rows of plan samples evaluated at once when the sample times are not on the filter's grid.
_CHUNK_ROWS = 200_000


@dataclass(frozen=True)
class FirSettings:
    """Taps ``n``, period ``T`` (s) and the filter's share of the path tolerance ``P_f`` (m)."""

    taps: int
    period_s: float
    filter_tolerance_m: float
    corner_tolerance_m: float
    #: How far (m) :func:`pushed_corners` moves a capped blend's corner out of the turn (0: none).
    push_m: float = 0.0

    @property
    def window_s(self) -> float:
        """``(n - 1) T``, s: the span of the samples averaged, the motion's lengthening and a corner stop's hold."""
        return (self.taps - 1) * self.period_s

    def max_window_m(self, arc: ArcSegment, written: bool = False) -> float:
        """The longest path length the samples may span on ``arc`` (module notes), m; a ``written`` arc (not a
        blend's, which has used the rest of P) may take the whole tolerance."""
        curvature = arc.radius_m * (arc.sweep_rad / arc.length_m) ** 2
        if self.taps < 2 or curvature <= 0.0:
            return math.inf
        tolerance_m = self.corner_tolerance_m if written else self.filter_tolerance_m
        span = math.sqrt(24.0 * tolerance_m / curvature) * (self.taps - 1) \
            / math.sqrt(self.taps * self.taps - 1.0)
        if span <= arc.length_m:
            return span
        return min(span, max(arc.length_m, 8.0 * self.corner_tolerance_m / abs(arc.sweep_rad)))


def fir_settings(limits: AxisLimits, period_s: float, tolerance_m: float, share: float) -> FirSettings:
    """The filter of ``limits`` (with ``max_jerk_m_s3``) at ``period_s`` (s) and ``share`` of ``tolerance_m`` (m)."""
    return FirSettings(filter_taps(limits, period_s), period_s, share * tolerance_m, tolerance_m,
                       PUSH_SHARE * tolerance_m)


def kink_acceleration_m_s2(max_velocity_m_s: FloatArray, max_acceleration_m_s2: FloatArray, settings: FirSettings,
                           tolerance_rad: float) -> FloatArray:
    """The axis accelerations (m/s², ``(n_axes,)``) the fir plan is planned with: the limits' less what a junction
    passed at speed (a turn of at most ``tolerance_rad``, taken as straight) adds to the filtered acceleration.

    Across such a kink the velocity turns by ``θ`` in no time, so the mean over the window ``T_w`` of the axis
    acceleration is ``(v(t) T_j' - v(t - T_w) T_j) / T_w``: the tangential part on the new direction (at most
    ``a |T_j| + a θ``) and the turn's ``v θ / T_w``. With ``v <= |vmax|`` and ``a <= |amax|`` (2-norms) each axis
    keeps ``θ (|amax| + |vmax| / T_w)`` in reserve (at most half its limit), one kink per window; a plan solved
    to the limit on a segment next to the kink then holds it after the filter.
    """
    acceleration = np.asarray(max_acceleration_m_s2, dtype=float)
    if settings.window_s <= 0.0 or tolerance_rad <= 0.0:
        return acceleration
    reserve = tolerance_rad * (float(np.linalg.norm(acceleration))
                               + float(np.linalg.norm(max_velocity_m_s)) / settings.window_s)
    return np.maximum(acceleration - reserve, 0.5 * acceleration)


#: Shares of the caps' tolerances :func:`fir_attempts` plans with, in order, the last one stopping at every corner.
ATTEMPT_SHARES = (1.0, 1.0, 0.25, 0.25)
#: Share of P a capped blend's corner is pushed out of the turn by (:func:`pushed_corners`), first attempt only.
PUSH_SHARE = 0.9


def fir_attempts(settings: FirSettings, blend_tolerance_m: float) -> list[tuple[FirSettings, float]]:
    """``settings`` with its caps' tolerances at each of :data:`ATTEMPT_SHARES` (tighter caps, slower curves), and
    the blends' tolerance (m): ``blend_tolerance_m``, in the last attempt 0 (every corner a stop, held). Only the
    first attempt pushes corners out (``push_m``)."""
    return [(dataclasses.replace(settings, filter_tolerance_m=share * settings.filter_tolerance_m,
                                 corner_tolerance_m=share * settings.corner_tolerance_m,
                                 push_m=settings.push_m if k == 0 else 0.0),
             blend_tolerance_m if k < len(ATTEMPT_SHARES) - 1 else 0.0) for k, share in enumerate(ATTEMPT_SHARES)]


def within_tolerance(plan: Callable[[FloatArray], ReferenceTrajectory], duration_s: float, settings: FirSettings,
                     blended: BlendedProgram, tolerance_m: float) -> bool:
    """Whether the filtered reference of the plan (``plan(times)``, before the filter) is within ``tolerance_m`` (m)
    of the programmed path at every multiple of the filter's period up to ``duration_s`` (s): the check of the
    caps' estimates. Each point is measured exactly to the programmed segments its samples come from (and the
    one before, a blend's other side): a convex combination of points of those segments."""
    n, period = settings.taps, settings.period_s
    grid = np.asarray(period * np.arange(-(n - 1), math.ceil(duration_s / period) + 1), np.float64)
    raw = plan(grid)
    points = moving_average_rows(raw.position_m, n)
    sources = np.asarray(blended.source_segment or range(len(blended.planned.segments)), dtype=np.intp)
    first = np.maximum(sources[raw.segment_index[:points.shape[0]]] - 1, 0)
    last = sources[raw.segment_index[n - 1:]]
    distance = np.full(points.shape[0], np.inf)
    for j in range(int(first.min(initial=0)), int(last.max(initial=-1)) + 1):
        rows = slice(int(np.searchsorted(last, j, side="left")), int(np.searchsorted(first, j, side="right")))
        if rows.start < rows.stop:
            near = blended.programmed.segments[j].nearest(points[rows])[0]
            distance[rows] = np.minimum(distance[rows], near)
    return bool(distance.max(initial=0.0) <= tolerance_m)


def capped_program(program: Program, settings: FirSettings, written: Program | None = None) -> Program:
    """``program`` with each arc's feed capped so that the filter's samples span at most its window (m/s); the arcs
    of ``written`` (the program as written) are not blends."""
    kept = {id(segment) for segment in written.segments} if written is not None else set()
    if settings.window_s <= 0.0:
        return program
    program, pushed = pushed_corners(program, settings, kept)
    wider = dataclasses.replace(settings, filter_tolerance_m=settings.filter_tolerance_m + settings.push_m,
                                corner_tolerance_m=settings.corner_tolerance_m + settings.push_m)
    segments, changed = list(program.segments), False
    for k, segment in enumerate(segments):
        if isinstance(segment, ArcSegment):
            cap = (wider if k in pushed else settings).max_window_m(segment, id(segment) in kept) / settings.window_s
            if cap < segment.feed_m_s:
                segments[k], changed = dataclasses.replace(segment, feed_m_s=cap), True
    return dataclasses.replace(program, segments=tuple(segments)) if changed else program


def _refillet(arc: ArcSegment, before: FloatArray, vertex: FloatArray, after: FloatArray) -> ArcSegment | None:
    """``arc``'s radius, filleting the lines along unit ``before`` and ``after`` that meet at ``vertex``."""
    turn = math.acos(min(1.0, max(-1.0, float(before @ after))))
    inward = after - before
    if not 0.0 < turn < 0.75 * math.pi:
        return None
    inward = inward / float(np.linalg.norm(inward))
    reach = arc.radius_m * math.tan(0.5 * turn)
    refit = ArcSegment(vertex - reach * before, vertex + reach * after,
                       vertex + arc.radius_m / math.cos(0.5 * turn) * inward, arc.clockwise, arc.plane, arc.feed_m_s,
                       arc.source_line)
    return refit if abs(refit.sweep_rad - arc.sweep_rad) <= 0.5 * abs(arc.sweep_rad) else None  # same way round


def pushed_corners(program: Program, settings: FirSettings, kept: set[int]) -> tuple[Program, set[int]]:
    """``program`` with its capped blends' corners moved ``push_m`` out of their turns, and the pushed arcs' indices.

    A blend arc between two lines of its plane whose filter cap binds (below its feed) is re-filleted, at its radius,
    at its corner moved ``push_m / cos(θ/2)`` along the bisector away from its centre: where both lines' corners
    move, the lines move ``push_m`` out, parallel. The mean then cuts the corner from ``push_m`` outside, so the
    cap may take ``push_m`` more (:func:`capped_program`). A line moves only when both its ends are such blends
    (the others keep their ends: no new kink). The plan, not the reference, leaves the path by up to ``push_m``;
    :func:`within_tolerance` judges the reference, and the next attempt plans without pushing.
    """
    segments = list(program.segments)
    if settings.push_m <= 0.0 or len(segments) < 3:
        return program, set()
    lines = {k: s for k, s in enumerate(segments) if isinstance(s, LineSegment)}
    arcs = {k: s for k, s in enumerate(segments) if isinstance(s, ArcSegment) and id(s) not in kept and s.is_planar}
    fillets = {k for k, arc in arcs.items() if k - 1 in lines and k + 1 in lines
               and not any(np.any(lines[j].unit_vector[[i for i in range(arc.n_axes) if i not in arc.plane]])
                           for j in (k - 1, k + 1))}
    movable = {k for k in lines if k - 1 in fillets and k + 1 in fillets}
    pushed = {k for k in fillets if k - 1 in movable and k + 1 in movable
              and settings.max_window_m(arcs[k]) / settings.window_s < arcs[k].feed_m_s}
    if not pushed:
        return program, set()
    vertex: dict[int, FloatArray] = {}
    for k in fillets:
        arc, half = arcs[k], 0.5 * abs(arcs[k].sweep_rad)
        corner = arc.start_m + arc.radius_m * math.tan(half) * lines[k - 1].unit_vector
        centre = arc.start_m.copy()
        centre[list(arc.plane)] = arc.center_m[list(arc.plane)]
        out = (corner - centre) / float(np.linalg.norm(corner - centre))
        vertex[k] = corner + (settings.push_m / math.cos(half) if k in pushed else 0.0) * out
    moved = {k for k in movable if k - 1 in pushed or k + 1 in pushed}
    direction = {k: lines[k].unit_vector for k in lines}
    direction.update({k: (vertex[k + 1] - vertex[k - 1]) / float(np.linalg.norm(vertex[k + 1] - vertex[k - 1]))
                      for k in moved})
    out_segments = list(segments)
    for k in {j for m in moved for j in (m - 1, m + 1)}:
        refit = _refillet(arcs[k], direction[k - 1], vertex[k], direction[k + 1])
        if refit is None:
            return program, set()
        out_segments[k] = refit
    for k in {j for m in moved for j in (m - 2, m, m + 2)} & set(lines):
        line, before, after = lines[k], out_segments[k - 1], out_segments[(k + 1) % len(segments)]
        start = before.end_m if k - 1 in fillets and isinstance(before, ArcSegment) else line.start_m
        end = after.start_m if k + 1 in fillets and isinstance(after, ArcSegment) else line.end_m
        if float((end - start) @ line.unit_vector) < 0.5 * line.length_m:
            return program, set()
        out_segments[k] = LineSegment(start, end, line.feed_m_s, line.source_line)
    return dataclasses.replace(program, segments=tuple(out_segments)), pushed


def stop_holds_s(program: Program, speeds_m_s: FloatArray, tolerance_rad: float, settings: FirSettings,
                 accel_m_s2: FloatArray) -> FloatArray:
    """Each junction's dwell (s, ``(N + 1,)``): the program's, and a hold where it stops at a turn.

    Between two lines the hold is ``T_w - (48 n T P / (a sin θ))^(1/3)`` (``a``: the larger of the two lines'
    tangential accelerations ``accel_m_s2`` (m/s²), ``P``: the corner share): braking at ``a``, the samples of
    the other line lie ``a τ² / 2`` from the corner, and the window's mean is at most
    ``a sin θ (T_w - H)³ / (48 n T)`` off the nearer line (from 90° on, ``sin θ`` is taken as 1: the nearer
    point of a line is then its end, the corner). Next to an arc: ``T_w``.
    """
    dwell = np.array(program.junction_dwell_s, dtype=float)
    if len(program.segments) < 2 or settings.window_s <= 0.0:
        return dwell
    turns = junction_turns_rad(program.segments)
    for k in np.flatnonzero((turns > tolerance_rad) & (speeds_m_s[1:-1] <= 0.0)).tolist():
        hold = settings.window_s
        before, after = program.segments[k], program.segments[k + 1]
        if not isinstance(before, ArcSegment) and not isinstance(after, ArcSegment):
            a = max(float(accel_m_s2[k]), float(accel_m_s2[k + 1]), 1e-300)
            reach = (48.0 * settings.taps * settings.period_s * settings.corner_tolerance_m
                     / (a * math.sin(min(float(turns[k]), 0.5 * math.pi)))) ** (1.0 / 3.0)
            hold = max(settings.window_s - reach, 0.0)
        dwell[k + 1] = max(dwell[k + 1], hold)
    return dwell


def _on_grid(t: FloatArray, period_s: float) -> bool:
    return t.size >= 2 and bool(np.all(np.abs(np.diff(t) - period_s) <= 1e-9 * period_s))


def filtered_array(plan: Callable[[FloatArray], ReferenceTrajectory], times_s: FloatArray, settings: FirSettings,
                   duration_s: float) -> FilteredArrays:
    """The filtered reference at ``times_s`` (s, ``(M,)``) of the plan's ``plan(times)`` (one ends ``duration_s``).

    Positions, velocities and accelerations are the means of the plan's at the ``n`` sample times; path length,
    segment and ``done`` the plan's at the middle one; the feed the filtered velocity's norm; ``done`` from
    ``duration_s`` on (every sample past the plan's end).
    """
    t, n, period = np.asarray(times_s, dtype=float), settings.taps, settings.period_s
    if _on_grid(t, period):
        raw = plan(t[0] + period * np.arange(-(n - 1), t.size))
        middle = slice((n - 1) // 2, (n - 1) // 2 + t.size)
        axes = [moving_average_rows(x, n) for x in (raw.position_m, raw.velocity_m_s, raw.acceleration_m_s2)]
        fields = (raw.path_length_m[middle], raw.segment_index[middle])
    else:
        axes_parts: list[list[FloatArray]] = [[], [], []]
        path_parts: list[FloatArray] = []
        index_parts: list[np.ndarray] = []
        step = max(1, _CHUNK_ROWS // n)
        offsets = period * np.arange(-(n - 1), 1)
        for start in range(0, t.size, step):
            rows = t[start:start + step]
            raw = plan((rows[:, None] + offsets[None, :]).reshape(-1))
            for part, x in zip(axes_parts, (raw.position_m, raw.velocity_m_s, raw.acceleration_m_s2)):
                part.append(x.reshape(rows.size, n, -1).mean(axis=1))
            path_parts.append(raw.path_length_m.reshape(rows.size, n)[:, (n - 1) // 2])
            index_parts.append(raw.segment_index.reshape(rows.size, n)[:, (n - 1) // 2])
        axes = [np.concatenate(part) if part else np.zeros((0, 0)) for part in axes_parts]
        fields = (np.concatenate(path_parts) if path_parts else np.zeros(0),
                  np.concatenate(index_parts) if index_parts else np.zeros(0, dtype=np.intp))
    done = t >= duration_s
    feed = np.linalg.norm(axes[1], axis=1) if axes[1].size else np.zeros(t.size)
    return t, axes[0], axes[1], axes[2], fields[0], fields[1].astype(np.intp), feed, done


class LiveJerkFilter:
    """The filter on the override's retimed reference, one tick at a time (what :class:`LiveReference` runs).

    ``n = ceil(2 amax_j / (jmax_j T))`` over the machine's ``limits`` at the tick period ``T`` (the difference of
    the first two stamps, fixed after). The sample's path length, segment and feed are the middle tick's; ``done``
    once the last ``n`` samples are all done (the filter drained at the program's end).
    """

    def __init__(self, limits: AxisLimits) -> None:
        self.limits = limits
        self._average: MovingAverage | None = None
        self._first: ReferenceSample | None = None
        self._last_ns, self._period_ns = -1, 0
        self._recent: deque[ReferenceSample] = deque(maxlen=1)
        self._done_run = 0

    def step(self, stamp_ns: int, sample: ReferenceSample) -> ReferenceSample:
        """The filtered ``sample`` of the tick at ``stamp_ns`` (ns); an earlier or equal stamp restarts it."""
        if self._first is None or stamp_ns <= self._last_ns:
            self._first, self._average, self._last_ns = sample, None, stamp_ns
            self._recent, self._done_run = deque([sample], maxlen=1), 0
            zeros = np.zeros_like(sample.velocity_m_s)
            return dataclasses.replace(sample, velocity_m_s=zeros, acceleration_m_s2=zeros.copy(), feed_m_s=0.0,
                                       done=False)
        if self._average is None:
            self._start(stamp_ns - self._last_ns)
        elif stamp_ns - self._last_ns != self._period_ns:
            raise ConfigError(f"the jerk filter needs a fixed tick period {self._period_ns} ns, "
                              f"got {stamp_ns - self._last_ns} ns at stamp {stamp_ns} ns")
        assert self._average is not None
        self._last_ns = stamp_ns
        self._recent.append(sample)
        self._done_run = self._done_run + 1 if sample.done else 0
        values = self._average.step(np.concatenate([sample.position_m, sample.velocity_m_s,
                                                    sample.acceleration_m_s2]).tolist())
        n, middle = len(sample.position_m), self._recent[(len(self._recent) - 1) // 2]
        velocity = np.array(values[n:2 * n])
        return dataclasses.replace(middle, position_m=np.array(values[:n]), velocity_m_s=velocity,
                                   acceleration_m_s2=np.array(values[2 * n:]),
                                   feed_m_s=float(np.linalg.norm(velocity)),
                                   done=self._done_run >= self._average.taps,
                                   feed_override_ratio=sample.feed_override_ratio)

    def _start(self, period_ns: int) -> None:
        assert self._first is not None
        self._period_ns = period_ns
        taps = filter_taps(self.limits, period_ns * 1e-9)
        first = self._first
        self._average = MovingAverage(taps, 3 * len(first.position_m))
        self._average.reset(np.concatenate([first.position_m, np.zeros(2 * len(first.position_m))]).tolist())
        self._recent = deque([first] * (taps - 1), maxlen=taps)
