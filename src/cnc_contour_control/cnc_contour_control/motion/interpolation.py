"""Trajectory interpolation: a trapezoidal, acceleration-limited feed profile over a program.

The path speed ``v(τ)`` is piecewise linear in the profile time ``τ``
(accelerate, cruise, decelerate within each segment). The axis references are

    position     p(τ) = P(s(τ))
    velocity     v(τ) T(s)
    acceleration a_t(τ) T(s) + v(τ)**2 K(s)

with ``T`` the unit tangent and ``K`` the curvature vector of the segment.
Per-axis limits hold because each segment's speed keeps ``v |T_j| <= vmax_j``
and, on arcs, ``v**2 |K_j| <= f amax_j`` while ``|a_t T_j| <= (1 - f) amax_j``
(``f`` = ``arc_centripetal_fraction``). Speed is zero at the program's start
and end and at sharp corners; across tangent-continuous junctions it is
continuous. A program's dwells (G4, ``Program.dwells``) are phases at rest
at their junction, which is then a stop. A junction whose tangents differ by less than
``corner_angle_tolerance_deg`` but not exactly gets a step in the axis
velocities of at most ``v * angle``; that step is the one place where the
finite-difference acceleration can exceed the limits. The default tolerance
(1e-4 deg, 1.7 µrad) only absorbs rounding in exactly tangent geometry; raise
it for G-code with few decimals, knowing the step it allows.

With ``arc_combined_budget`` an arc's speed range is split into
``arc_speed_bands`` bands, each with the budget at its highest speed
(:func:`cnc_contour_control.motion.arc_budget.speed_bands`): its accelerate and
decelerate phases are one constant-acceleration phase per band crossed.
``look_ahead_segments`` caps each junction's speed so that the segments in
that window can brake to rest (:func:`~cnc_contour_control.motion.plan_arrays.look_ahead_caps_m_s`).

With a path tolerance (``path_tolerance_mm``, or G64 P) the profile is planned over the blended program
(:mod:`cnc_contour_control.motion.blending`; :attr:`Interpolator.program`; the one written:
:attr:`Interpolator.programmed_program`), or as written if that is quicker (never slower than exact stop).
With a jerk limit (``AxisLimits.max_jerk_m_s3``) ``jerk_mode`` ``fir`` passes that plan through a moving average
(:mod:`cnc_contour_control.motion.jerk_fir`), ``scurve`` plans S-curves (:mod:`cnc_contour_control.motion.jerk_plan`),
``quickest`` plans both and keeps the quicker (``fir`` is the default) (:attr:`Interpolator.jerk_mode_used`).
"""
from __future__ import annotations

import bisect
import dataclasses
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnc_contour_control.core.config import require_non_negative
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.accel_decel import ReferenceFilter
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.blend_choice import CornerLimits
from cnc_contour_control.motion.blending import BlendedProgram, quickest_blend
from cnc_contour_control.motion.geometry import Program, Segment
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.jerk_fir import (
    FirSettings,
    capped_program,
    filtered_array,
    fir_attempts,
    fir_settings,
    kink_acceleration_m_s2,
    stop_holds_s,
    within_tolerance,
)
from cnc_contour_control.motion.jerk_plan import JerkPlan, quickest_jerk_plan
from cnc_contour_control.motion.plan_arrays import (
    SpeedBands,
    banded_phases,
    plan_banded_limits,
    program_junction_speeds_m_s,
)
from cnc_contour_control.motion.reference_types import ReferenceSample, ReferenceTrajectory
from cnc_contour_control.motion.stream_start import start_stream, whole_plan

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SegmentLimits:
    """Planning limits of one segment: cruise speed (m/s) and tangential acceleration (m/s^2)."""

    speed_m_s: float
    acceleration_m_s2: float


def _plan_limits(segments: Sequence[Segment], limits: AxisLimits, config: InterpolatorConfig,
                 first_index: int = 0) -> tuple[FloatArray, FloatArray, SpeedBands]:
    return plan_banded_limits(segments, np.asarray(limits.max_velocity_m_s), np.asarray(limits.max_acceleration_m_s2),
                              config.arc_centripetal_fraction, config.arc_combined_budget, config.clamp_feed,
                              first_index, config.arc_speed_bands)


def planning_tolerance_m(program: Program, config: InterpolatorConfig) -> float:
    """The blend tolerance, m: the program's (G64 P / G61) if it sets one, else ``config.path_tolerance_mm``."""
    if program.path_tolerance_m is not None:
        return program.path_tolerance_m
    return config.path_tolerance_mm * 1.0e-3


def with_planning_tolerance(program: Program, config: InterpolatorConfig) -> Program:
    """``program`` carrying the tolerance it is planned with (:func:`planning_tolerance_m`) as ``path_tolerance_m``.

    What a run records, so that the scorer can set the reference's deviation beside it. The same object
    when the program already sets it (G64 P / G61).
    """
    tolerance_m = planning_tolerance_m(program, config)
    if program.path_tolerance_m == tolerance_m:
        return program
    return dataclasses.replace(program, path_tolerance_m=tolerance_m)


class Interpolator:
    """Plans a trapezoidal feed profile over ``program`` and evaluates it analytically.

    Parameters
    ----------
    program : Program
        The contour.
    limits : AxisLimits
        Per-axis limits, one entry per program axis.
    config : InterpolatorConfig, optional
        Planner options.

    Notes
    -----
    :meth:`sample` is stateless (time ``t_s`` from the profile's start).
    :meth:`advance` keeps a profile time τ for feed override: each call moves
    τ by ``override_ratio * dt_s`` and returns the sample at τ with velocity
    and feed scaled by the ratio and acceleration by its square (the term from
    a changing ratio, ``dk/dt * v``, is left out). Limits hold for ratios <= 1.

    A window (``look_ahead_segments``) shorter than the program plans it streaming
    (:mod:`cnc_contour_control.motion.plan_stream`): the constructor plans one chunk, :meth:`sample`,
    :meth:`sample_array` and :meth:`advance` extend the plan as time reaches its end; :attr:`duration_s`,
    :attr:`junction_speeds_m_s` and the other whole-plan arrays plan to the end on first use, :attr:`program`
    and :attr:`blended` blend the whole program on first use.
    """

    def __init__(self, program: Program, limits: AxisLimits, config: InterpolatorConfig | None = None) -> None:
        self.limits = limits
        self.config = config if config is not None else InterpolatorConfig()
        tolerance_rad = math.radians(self.config.corner_angle_tolerance_deg)
        if limits.n_axes != program.n_axes:
            raise ConfigError(
                f"limits must have one entry per program axis ({program.n_axes}: {list(program.axis_names)}), "
                f"got {limits.n_axes}")
        #: The program as written; :attr:`program` is the planned one (with blends).
        self.programmed_program = program
        self._profile_time_s, self._accel_decel = 0.0, ReferenceFilter(self.config.accel_decel)
        tolerance_m, jerk_mode = planning_tolerance_m(program, self.config), self.config.jerk_mode
        self._fir = None if limits.max_jerk_m_s3 is None or jerk_mode == "scurve" or tolerance_m <= 0.0 else \
            fir_settings(limits, self.config.jerk_filter_period_s, tolerance_m, self.config.jerk_filter_tolerance_share)
        tolerance_m -= 0.0 if self._fir is None else self._fir.filter_tolerance_m
        self._jerk = None if limits.max_jerk_m_s3 is None or self._fir else self._plan_jerk(program, tolerance_m)
        self._stream = None if self._jerk else start_stream(self, program, limits, tolerance_m, self._fir,
                                                            planning_tolerance_m(program, self.config))
        #: The jerk-limited mode that runs (``fir`` or ``scurve``; ``jerk_mode`` quickest: the quicker), or None.
        self.jerk_mode_used = None if limits.max_jerk_m_s3 is None else "fir" if self._fir else "scurve"
        if self._stream is not None or self._jerk is not None:
            return
        self._end_point_m = program.segments[-1].point(program.segments[-1].length_m)
        for fir, blend_m in [(None, tolerance_m)] if self._fir is None else fir_attempts(self._fir, tolerance_m):
            self._fir = fir
            self._plan_blended(program, blend_m, tolerance_rad)
            if fir is None or within_tolerance(self._plan_array, self.duration_s, fir, self.blended,
                                               planning_tolerance_m(program, self.config)):
                if fir is not None and jerk_mode == "quickest":
                    self._compare_scurve(program)
                return
        self._fir, self._jerk = None, self._plan_jerk(program, planning_tolerance_m(program, self.config))
        self.jerk_mode_used = "scurve"

    def _compare_scurve(self, program: Program) -> None:
        """``jerk_mode`` quickest after a FIR plan: the ``scurve`` plan instead where it is quicker (programs of at
        most ``jerk_compare_max_segments`` segments; a tie keeps ``fir``, whose override ramps are jerk-limited)."""
        if len(program.segments) > self.config.jerk_compare_max_segments:
            return
        tolerance_m = planning_tolerance_m(program, self.config)
        plan = quickest_jerk_plan(program, self.limits, self.config.clamp_feed, tolerance_m)
        if plan.duration_s < self.duration_s:
            self._fir, self._jerk, self.jerk_mode_used = None, self._plan_jerk(program, tolerance_m, plan), "scurve"

    def _plan_blended(self, program: Program, tolerance_m: float, tolerance_rad: float) -> None:
        """The (v, a) plan over the quickest blend of ``program`` (:func:`quickest_blend`)."""
        self._plans: dict[int, dict[str, Any]] = {}
        blended = quickest_blend(program, tolerance_m, tolerance_rad, CornerLimits(
            np.asarray(self.limits.max_velocity_m_s), np.asarray(self._planning_limits().max_acceleration_m_s2),
            self.config.arc_centripetal_fraction), self._planned_duration_s)
        self.__dict__.update(self._plans.pop(id(blended.planned)))  # an earlier attempt's blend is in the snapshots
        self.blended = blended
        del self._plans
        self._plan_end_s = self.duration_s  # fir: the program ends when the filter has drained
        self.duration_s += 0.0 if self._fir is None else self._fir.window_s

    def _plan_jerk(self, program: Program, tolerance_m: float, plan: JerkPlan | None = None) -> JerkPlan:
        """The jerk-limited mode (:mod:`~cnc_contour_control.motion.jerk_plan`; its corners are not in
        :attr:`program`); ``plan`` if given (planned at ``tolerance_m``)."""
        if plan is None:
            plan = quickest_jerk_plan(program, self.limits, self.config.clamp_feed, tolerance_m)
        self.blended, self.program, self._view = BlendedProgram.unblended(program, tolerance_m), program, program
        self.duration_s, self.cruise_speed_m_s = plan.duration_s, plan.peak_speed_m_s
        self.tangential_acceleration_m_s2 = np.array([p.accel_m_s2 for p in plan.path_limits])
        self.junction_speeds_m_s = plan.junction_speeds_m_s
        self._end_point_m = program.segments[-1].point(program.segments[-1].length_m)
        return plan

    def __getattr__(self, name: str) -> Any:
        """Streaming: the whole plan's attributes, planned to the end on first use (:func:`stream_start.whole_plan`)."""
        if name.startswith("__") or self.__dict__.get("_stream") is None:
            raise AttributeError(name)
        self.__dict__.update(whole_plan(self, name))
        return self.__dict__[name]

    @property
    def jerk_filter(self) -> FirSettings | None:
        """The FIR jerk filter's taps, period and tolerance share (``jerk_mode`` fir with a jerk limit), else None."""
        return self._fir

    def planned_end_s(self, t_s: float) -> float:
        """The profile's duration (s), or inf while a streaming plan has not reached it after planning past ``t_s``.

        What a per-tick caller (feed override) bounds τ with without finishing a streaming plan (:attr:`duration_s`
        does)."""
        return self.duration_s if self._stream is None else self._stream.extend_to(t_s)

    @functools.cached_property
    def segment_limits(self) -> list[SegmentLimits]:
        """Cruise speed and tangential acceleration per planned segment (:attr:`cruise_speed_m_s`, ...)."""
        return [SegmentLimits(v, a) for v, a in zip(self.cruise_speed_m_s.tolist(),
                                                     self.tangential_acceleration_m_s2.tolist())]

    def _plan(self, program: Program) -> None:
        tolerance_rad = math.radians(self.config.corner_angle_tolerance_deg)
        program = program if self._fir is None else capped_program(program, self._fir, self.programmed_program)
        self.program = self._view = program
        self.cruise_speed_m_s, self.tangential_acceleration_m_s2, self.speed_bands = _plan_limits(
            program.segments, self._planning_limits(), self.config)
        self.junction_speeds_m_s = program_junction_speeds_m_s(program, self.cruise_speed_m_s, self.speed_bands,
                                                               tolerance_rad, self.config.look_ahead_segments)
        speeds = self.junction_speeds_m_s
        lengths = np.array([segment.length_m for segment in self.program.segments])
        dwell = program.junction_dwell_s if self._fir is None else stop_holds_s(
            program, speeds, tolerance_rad, self._fir, self.tangential_acceleration_m_s2)
        self._phases = phases = banded_phases(lengths, speeds[:-1], speeds[1:], self.cruise_speed_m_s,
                                              self.speed_bands, dwell)
        self._phase_start_s = phases.start_s[:-1].tolist()
        self._phase_s0_m, self._phase_v0_m_s = phases.s0_m.tolist(), phases.v0_m_s.tolist()
        self._phase_accel_m_s2, self._phase_segment = phases.accel_m_s2.tolist(), phases.segment.tolist()
        self.duration_s = float(phases.start_s[-1])

    def _planning_limits(self) -> AxisLimits:
        """:attr:`limits`, with a fir plan's accelerations less its kinks' reserve (:func:`kink_acceleration_m_s2`)."""
        if self._fir is None:
            return self.limits
        limits = self.limits
        accel = kink_acceleration_m_s2(np.asarray(limits.max_velocity_m_s), np.asarray(limits.max_acceleration_m_s2),
                                       self._fir, math.radians(self.config.corner_angle_tolerance_deg))
        return dataclasses.replace(limits, max_acceleration_m_s2=tuple(accel.tolist()))

    def _planned_duration_s(self, program: Program) -> float:
        """Plan ``program`` and keep that plan (:func:`~cnc_contour_control.motion.blending.quickest_blend` compares
        plans: never slower than exact stop)."""
        self._plan(program)
        self._plans[id(program)] = {k: v for k, v in self.__dict__.items() if k != "_plans"}
        return self.duration_s

    @property
    def phase_count(self) -> int:
        """Number of constant-acceleration phases of the profile."""
        return len(self._phases.start_s) - 1

    def _path_state(self, t_s: float) -> tuple[int, float, float, float]:
        """Segment index, local arc length (m), path speed (m/s) and path acceleration (m/s^2) at ``t_s``."""
        if t_s < 0.0:
            return 0, 0.0, 0.0, 0.0
        k = max(bisect.bisect_right(self._phase_start_s, t_s) - 1, 0)
        dt = max(t_s - self._phase_start_s[k], 0.0)
        v0, accel = self._phase_v0_m_s[k], self._phase_accel_m_s2[k]
        s_local = self._phase_s0_m[k] + v0 * dt + 0.5 * accel * dt * dt
        return self._phase_segment[k], s_local, max(v0 + accel * dt, 0.0), accel

    def sample(self, t_s: float) -> ReferenceSample:
        """The reference at profile time ``t_s`` (s); before 0 holds the start, after the end holds the end."""
        if self._fir is None or math.isnan(t_s) or t_s >= self._filtered_end_s(t_s):
            return self.plan_sample(t_s)
        row = self.sample_array([t_s])
        return ReferenceSample(row.position_m[0], row.velocity_m_s[0], row.acceleration_m_s2[0],
                               float(row.path_length_m[0]), int(row.segment_index[0]), float(row.feed_m_s[0]),
                               self._view.segments[int(row.segment_index[0])].feed_m_s, False,
                               profile_time_s=max(t_s, 0.0))

    def plan_sample(self, t_s: float) -> ReferenceSample:
        """:meth:`sample` before the jerk filter (``jerk_mode`` ``fir``; the same otherwise): what an override
        retimes."""
        if math.isnan(t_s):
            raise ConfigError(f"t_s must be a number, got {t_s}")
        if t_s >= self._unfiltered_end_s(t_s):
            return self._end_sample()
        if self._jerk is not None:
            row = self.sample_array([t_s])
            return ReferenceSample(row.position_m[0], row.velocity_m_s[0], row.acceleration_m_s2[0],
                                   float(row.path_length_m[0]), int(row.segment_index[0]), float(row.feed_m_s[0]),
                                   self._view.segments[int(row.segment_index[0])].feed_m_s, False,
                                   profile_time_s=max(t_s, 0.0))
        index, s_local, speed, accel = self._path_state(t_s)
        segment = self._view.segments[index]
        s_local = min(max(s_local, 0.0), segment.length_m)
        point, tangent, curvature = segment.frame(s_local)
        return ReferenceSample(
            position_m=point, velocity_m_s=speed * tangent,
            acceleration_m_s2=accel * tangent + (speed * speed) * curvature,
            path_length_m=float(self._view.segment_start_m[index]) + s_local, segment_index=index,
            feed_m_s=speed, programmed_feed_m_s=segment.feed_m_s, done=False, profile_time_s=max(t_s, 0.0))

    def _end_sample(self) -> ReferenceSample:
        view, zeros = self._view, np.zeros(self._view.n_axes)
        return ReferenceSample(
            position_m=self._end_point_m.copy(), velocity_m_s=zeros, acceleration_m_s2=zeros.copy(),
            path_length_m=view.total_length_m, segment_index=len(view.segments) - 1,
            feed_m_s=0.0, programmed_feed_m_s=view.segments[-1].feed_m_s, done=True,
            profile_time_s=self.duration_s)

    def sample_array(self, times_s: ArrayLike) -> ReferenceTrajectory:
        """The reference at many profile times at once.

        Parameters
        ----------
        times_s : array_like, shape (M,)
            Profile times, s.

        Returns
        -------
        ReferenceTrajectory
            Positions, velocities, accelerations of shape ``(M, n_axes)``.
        """
        t = np.asarray(times_s, dtype=float).reshape(-1)
        if self._fir is not None:
            end_s = self._filtered_end_s(float(np.max(t, initial=0.0)))
            return ReferenceTrajectory(*filtered_array(self._plan_array, t, self._fir, end_s))
        return self._plan_array(t)

    def _unfiltered_end_s(self, t_s: float) -> float:
        """The plan's end before the jerk filter (s), or inf while a stream has not reached it past ``t_s``."""
        if self._fir is not None and self._stream is None:
            return float(self._plan_end_s)
        return self.planned_end_s(t_s)

    def _filtered_end_s(self, t_s: float) -> float:
        """fir: the profile's end, the filter drained (s), or inf while a stream has not reached it past ``t_s``."""
        if self._stream is None:
            return float(self.duration_s)
        assert self._fir is not None
        return self._stream.extend_to(t_s) + self._fir.window_s

    def _plan_array(self, t: FloatArray) -> ReferenceTrajectory:
        """:meth:`sample_array` before the jerk filter."""
        if self._jerk is not None:
            index, s_local, speed, position, velocity, acceleration = self._jerk.axis_arrays(t)
            done = t >= self.duration_s
            position[done] = self._end_point_m
            path = np.where(done, self._view.total_length_m, self._view.segment_start_m[index] + s_local)
            return ReferenceTrajectory(t, position, velocity, acceleration, path, index, speed, done)
        end_s = self._unfiltered_end_s(float(np.max(t, initial=0.0)))
        clipped = np.clip(t, 0.0, end_s)
        phases = self._phases if self._stream is None else self._stream.phases()
        k = np.maximum(np.searchsorted(phases.start_s[:-1], clipped, side="right") - 1, 0)
        dt = np.maximum(clipped - phases.start_s[k], 0.0)
        v0, accel = phases.v0_m_s[k], phases.accel_m_s2[k]
        s_local = phases.s0_m[k] + v0 * dt + 0.5 * accel * dt * dt
        speed = np.maximum(v0 + accel * dt, 0.0)
        index = phases.segment[k]
        done = t >= end_s
        speed[done], accel[done | (t < 0.0)] = 0.0, 0.0
        arrays = self._axis_arrays(index, s_local, speed, accel, done)
        path = self._view.segment_start_m[index] + np.clip(s_local, 0.0, None)
        path[done] = self._view.total_length_m
        return ReferenceTrajectory(t, *arrays, path, index, speed, done)

    def _axis_arrays(self, index: NDArray[np.intp], s_local: FloatArray, speed: FloatArray,
                     accel: FloatArray, done: NDArray[np.bool_]) -> tuple[FloatArray, FloatArray, FloatArray]:
        n = self._view.n_axes
        position, velocity, acceleration = (np.zeros((index.size, n)) for _ in range(3))
        for i in np.unique(index):
            rows = np.flatnonzero(index == i)
            segment = self._view.segments[int(i)]
            s = np.clip(s_local[rows], 0.0, segment.length_m)
            tangent = segment.tangent(s)
            position[rows] = segment.point(s)
            velocity[rows] = speed[rows, None] * tangent
            acceleration[rows] = accel[rows, None] * tangent + (speed[rows] ** 2)[:, None] * segment.curvature_vector(s)
        if done.any():  # a stream knows its end point only once planned to it
            position[done] = self._end_point_m
        return position, velocity, acceleration

    def reference(self, t_s: float) -> ReferenceSample:
        """:meth:`sample` through the acceleration/deceleration (``config.accel_decel``): the servos' reference.

        Call at successive tick times (the filter keeps its state; an earlier
        time restarts it). Path length, segment, feed and ``done`` stay the
        unfiltered profile's. ``accel_decel.kind`` ``none``: :meth:`sample` itself.
        """
        sample = self.sample(t_s)
        if self.config.accel_decel.kind == "none":
            return sample
        n = self._view.n_axes
        flat = self._accel_decel.step(t_s, sample.position_m.tolist() + sample.velocity_m_s.tolist()
                                      + sample.acceleration_m_s2.tolist())
        return dataclasses.replace(sample, position_m=np.array(flat[:n]), velocity_m_s=np.array(flat[n:2 * n]),
                                   acceleration_m_s2=np.array(flat[2 * n:]))

    def reference_array(self, times_s: ArrayLike) -> ReferenceTrajectory:
        """:meth:`sample_array` through a fresh acceleration/deceleration filter, row by row as :meth:`reference`
        does."""
        trajectory = self.sample_array(times_s)
        if self.config.accel_decel.kind == "none":
            return trajectory
        n, accel_decel = self._view.n_axes, ReferenceFilter(self.config.accel_decel)
        rows = np.hstack([trajectory.position_m, trajectory.velocity_m_s, trajectory.acceleration_m_s2]).tolist()
        out = np.array([accel_decel.step(t, row) for t, row in zip(trajectory.time_s.tolist(), rows)], float)
        out = out.reshape(len(rows), 3 * n)
        return dataclasses.replace(trajectory, position_m=out[:, :n], velocity_m_s=out[:, n:2 * n],
                                   acceleration_m_s2=out[:, 2 * n:])

    def reset(self) -> None:
        """Return the profile time τ of :meth:`advance` and the acceleration/deceleration to the program start."""
        self._profile_time_s = 0.0
        self._accel_decel = ReferenceFilter(self.config.accel_decel)

    @property
    def profile_time_s(self) -> float:
        """The profile time τ reached by :meth:`advance`, s."""
        return self._profile_time_s

    def advance(self, dt_s: float, override_ratio: float = 1.0) -> ReferenceSample:
        """Move τ by ``override_ratio * dt_s`` and return the time-scaled reference there.

        Parameters
        ----------
        dt_s : float
            Elapsed time, s, >= 0 (use 0 for the first tick).
        override_ratio : float
            Feed override, >= 0 (0 holds the feed, 1 is the programmed feed).
        """
        dt = require_non_negative("dt_s", dt_s)
        ratio = require_non_negative("override_ratio", override_ratio)
        tau_s = self._profile_time_s + ratio * dt
        self._profile_time_s = min(tau_s, self.planned_end_s(tau_s))
        base = self.sample(self._profile_time_s)
        return ReferenceSample(
            position_m=base.position_m, velocity_m_s=ratio * base.velocity_m_s,
            acceleration_m_s2=(ratio * ratio) * base.acceleration_m_s2, path_length_m=base.path_length_m,
            segment_index=base.segment_index, feed_m_s=ratio * base.feed_m_s,
            programmed_feed_m_s=base.programmed_feed_m_s, done=base.done,
            profile_time_s=self._profile_time_s, feed_override_ratio=ratio)
