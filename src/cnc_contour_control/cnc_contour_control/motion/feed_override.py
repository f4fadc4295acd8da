"""Feed override on line: the planned profile time-scaled by a ratio that ramps within the axis limits (ROS-free).

The interpolator plans a profile ``p(τ)`` at the programmed feed. An override
ratio ``k(t)`` runs it at another pace, ``dτ/dt = k``, so the path stays the
programmed one and only the speed along it changes. The axis references become

    velocity      k v(τ) T
    acceleration  k² (a_t(τ) T + v(τ)² K) + k' v(τ) T

(``v``, ``a_t``, ``T``, ``K`` as in :mod:`cnc_contour_control.motion.interpolation`).
A ratio that jumped would make ``k'`` unbounded, so :class:`OverrideFollower`
moves the applied ratio towards the requested one each tick only as far as
every axis's velocity and acceleration limits allow at the new sample (the
largest feasible step, found by bisection; zero step is always feasible
while ``k`` is within ``max_ratio``, see below). 0 is feed hold: the ratio
ramps down to 0 and the reference stops on the path; a later ratio > 0
resumes it from there.

For ratios above 1 the profile must be planned for them:
:func:`planning_limits` scales the limits the planner sees by
``1/max_ratio`` (velocity) and ``1/max_ratio²`` (acceleration), so
``k² |a_t T + v² K| <= a_max`` and ``k v |T| <= v_max`` for every
``k <= max_ratio``. With ``max_ratio = 1`` (the default) nothing changes.

Discrete steps: the servo sees sampled positions, and their differences
are not the analytic values where the ratio and the profile's phase change
in the same tick. A step is therefore taken only if the analytic velocity
and acceleration *and* the first and second differences of the positions
(this sample and the two before it) keep the limits, the accelerations
within ``acceleration_share`` of them.

On line (:class:`LiveReference`, what the interpolator node and the engine
both call each tick; a streaming plan is planned ahead of the tool in a thread and forgotten behind it,
:mod:`cnc_contour_control.motion.plan_background`): the requested ratio of tick k is the step schedule's
value at t_k when ``schedule_times_s`` is given (an operator turning the
knob; 1 before its first time), else the latest ``feed_override`` message's
ratio (:func:`message_ratio`: its ``applied_ratio``, or a bare request's
``requested_ratio``); the follower's sample then passes the interpolator's
acceleration/deceleration filter, as :meth:`Interpolator.reference` does. A
filter is a positive-weight average of past samples, so it keeps the limits. With ``jerk_mode`` fir the
follower retimes the plan before the jerk filter (:class:`~cnc_contour_control.motion.jerk_fir.LiveJerkFilter`),
so the ratio's ramps come out jerk-limited too.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, replace

import numpy as np

from cnc_contour_control.core.config import require_finite, require_non_negative
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.lockstep import NS_PER_S, ns_to_s
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.motion.accel_decel import ReferenceFilter
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.jerk_fir import LiveJerkFilter
from cnc_contour_control.motion.plan_background import BackgroundPlanner
from cnc_contour_control.motion.plan_process import ProcessPlanner
from cnc_contour_control.motion.reference_types import ReferenceSample

_BISECTIONS = 40

#: Where the interpolator's requested ratio comes from (the node's ``feed_override_source``):
#: ``none`` no on-line override (the reference at the stamp); ``schedule`` the config's step schedule;
#: ``topic`` the latest ``feed_override`` message (an operator's node, a shop-floor stack);
#: ``previous_tick`` the message stamped at the previous tick, waited for (a force regulator in lockstep).
FEED_OVERRIDE_SOURCES = ("none", "schedule", "topic", "previous_tick")


@dataclass(frozen=True)
class OverrideConfig:
    """Options of the on-line feed override.

    Parameters
    ----------
    max_ratio : float
        The largest ratio applied, in [0, 2] (1.5 for a 0–150 % switch); the
        profile is planned for it (see :func:`planning_limits`).
    acceleration_share : float
        Share of each axis's acceleration limit the ramp may use, in (0, 1].
    schedule_times_s : tuple of float
        Times [s] of a step schedule of requested ratios, increasing, >= 0;
        empty: the requests come from the ``feed_override`` topic.
    schedule_ratios : tuple of float
        The ratio requested from each schedule time on, each in [0, max_ratio].
    """

    max_ratio: float = param(1.0, low=0.0, high=2.0, read_only=True,
                             description="largest feed override ratio applied (the profile is planned for it)")
    acceleration_share: float = param(0.98, low=0.05, high=1.0, read_only=True,
                                      description="share of each axis's acceleration limit a ratio ramp may use")
    schedule_times_s: tuple[float, ...] = param((), unit="s", read_only=True,
                                                description="times of a step schedule of requested ratios "
                                                            "(increasing); empty: requests from feed_override")
    schedule_ratios: tuple[float, ...] = param((), read_only=True,
                                               description="ratio requested from each schedule time on, "
                                                           "in [0, max_ratio]")

    def __post_init__(self) -> None:
        check_ranges(self)
        times = tuple(require_non_negative(f"schedule_times_s[{i}]", t) for i, t in enumerate(self.schedule_times_s))
        ratios = tuple(require_finite(f"schedule_ratios[{i}]", r) for i, r in enumerate(self.schedule_ratios))
        if len(times) != len(ratios):
            raise ConfigError(f"schedule_ratios must have one entry per schedule time ({len(times)}), "
                              f"got {len(ratios)}")
        for i in range(1, len(times)):
            if times[i] <= times[i - 1]:
                raise ConfigError(f"schedule_times_s must increase, got {times[i]} after {times[i - 1]} at entry {i}")
        for i, ratio in enumerate(ratios):
            if not 0.0 <= ratio <= self.max_ratio:
                raise ConfigError(f"schedule_ratios[{i}] must be in [0, max_ratio = {self.max_ratio}], got {ratio}")
        object.__setattr__(self, "schedule_times_s", times)
        object.__setattr__(self, "schedule_ratios", ratios)

    @property
    def has_schedule(self) -> bool:
        """True when the requests come from the schedule (not from the ``feed_override`` topic)."""
        return bool(self.schedule_times_s)

    def scheduled_ratio(self, t_s: float) -> float:
        """The schedule's requested ratio at ``t_s`` [s]: the last entry at or before it, 1 before the first."""
        index = bisect.bisect_right(self.schedule_times_s, t_s) - 1
        return self.schedule_ratios[index] if index >= 0 else 1.0


def planning_limits(limits: AxisLimits, config: OverrideConfig) -> AxisLimits:
    """The limits to plan with so every ratio up to ``max_ratio`` keeps ``limits`` (unchanged for <= 1): velocity
    ÷ k_max, acceleration ÷ k_max², jerk (if any) ÷ k_max³."""
    scale = max(config.max_ratio, 1.0)
    if scale == 1.0:
        return limits
    changes: dict[str, tuple[float, ...]] = {
        "max_velocity_m_s": tuple(v / scale for v in limits.max_velocity_m_s),
        "max_acceleration_m_s2": tuple(a / (scale * scale) for a in limits.max_acceleration_m_s2)}
    jerk = getattr(limits, "max_jerk_m_s3", None)  # jerk limits, where the limits have them: k³ j_plan <= j_max
    if jerk is not None:
        changes["max_jerk_m_s3"] = tuple(j / scale**3 for j in jerk)
    return replace(limits, **changes)


#: The planner of a streamed plan on line, by ``InterpolatorConfig.stream_planner``.
STREAM_PLANNER_CLASSES: dict[str, type[BackgroundPlanner]] = {"process": ProcessPlanner, "thread": BackgroundPlanner}


class OverrideFollower:
    """Advances an interpolator's profile at a feed override ratio that ramps within the axis limits.

    Parameters
    ----------
    interpolator : Interpolator
        Planned with :func:`planning_limits` of the machine's limits and ``config``.
    limits : AxisLimits
        The machine's axis limits (what the scaled reference must keep).
    config : OverrideConfig, optional
    """

    def __init__(self, interpolator: Interpolator, limits: AxisLimits, config: OverrideConfig | None = None) -> None:
        self.interpolator = interpolator
        self.config = config if config is not None else OverrideConfig()
        n_axes = interpolator.programmed_program.n_axes  # not .program: that would blend a streaming plan whole
        if limits.n_axes != n_axes:
            raise ConfigError(f"limits must have one entry per program axis ({n_axes}), "
                              f"got {limits.n_axes}")
        self._v_max = np.asarray(limits.max_velocity_m_s, dtype=float)
        self._a_max = np.asarray(limits.max_acceleration_m_s2, dtype=float) * self.config.acceleration_share
        self.reset()

    def reset(self, ratio: float = 1.0) -> None:
        """Back to the program start with the applied ratio at rest value ``ratio`` (the profile starts at rest)."""
        self.profile_time_s = 0.0
        self.ratio = self._clip(ratio)
        start = self.interpolator.plan_sample(0.0).position_m
        self._last_m, self._before_m = start, start

    def _clip(self, ratio: float) -> float:
        return min(max(require_finite("override ratio", ratio), 0.0), self.config.max_ratio)

    def _scaled(self, ratio: float, dt_s: float) -> tuple[ReferenceSample, bool]:
        """The sample one tick ahead at ``ratio`` and whether it keeps the limits."""
        tau = self.profile_time_s + ratio * dt_s
        tau = min(tau, self.interpolator.planned_end_s(tau))  # a streaming plan is extended, not finished
        base = self.interpolator.plan_sample(tau)  # before the jerk filter: LiveReference filters after the ratio
        rate = (ratio - self.ratio) / dt_s
        velocity = ratio * base.velocity_m_s
        acceleration = (ratio * ratio) * base.acceleration_m_s2 + rate * base.velocity_m_s
        step_m = base.position_m - self._last_m
        differenced = (step_m - (self._last_m - self._before_m)) / (dt_s * dt_s)
        ok = bool((np.abs(velocity) <= self._v_max).all() and (np.abs(step_m) <= self._v_max * dt_s).all()
                  and (np.abs(acceleration) <= self._a_max).all() and (np.abs(differenced) <= self._a_max).all())
        return replace(base, velocity_m_s=velocity, acceleration_m_s2=acceleration, feed_m_s=ratio * base.feed_m_s,
                       profile_time_s=tau, feed_override_ratio=ratio), ok

    def _largest_step(self, target: float, dt_s: float) -> tuple[float, ReferenceSample]:
        """The ratio nearest ``target`` on the way from the current one that keeps the limits, and its sample.

        At the ratio already applied there is nothing to bisect: the sample is the plan's own at that ratio (a plan
        accelerating at the limit fails the share's check there, and 41 samples per tick found the same one).
        """
        sample, ok = self._scaled(target, dt_s)
        if ok or target == self.ratio:
            return target, sample
        feasible, infeasible = self.ratio, target
        best = self._scaled(feasible, dt_s)[0]
        for _ in range(_BISECTIONS):
            middle = 0.5 * (feasible + infeasible)
            candidate, ok = self._scaled(middle, dt_s)
            if ok:
                feasible, best = middle, candidate
            else:
                infeasible = middle
        return feasible, best

    def advance(self, dt_s: float, requested_ratio: float) -> ReferenceSample:
        """One tick of ``dt_s`` towards ``requested_ratio`` (clipped to [0, max_ratio]); the new reference.

        The returned sample's ``feed_override_ratio`` is the ratio applied.
        ``dt_s = 0`` (the first tick) returns the current sample unchanged.
        """
        dt = require_non_negative("dt_s", dt_s)
        target = self._clip(requested_ratio)
        if dt == 0.0:
            base = self.interpolator.plan_sample(self.profile_time_s)
            return replace(base, velocity_m_s=self.ratio * base.velocity_m_s,
                           acceleration_m_s2=self.ratio ** 2 * base.acceleration_m_s2,
                           feed_m_s=self.ratio * base.feed_m_s, feed_override_ratio=self.ratio)
        ratio, sample = self._largest_step(target, dt)
        self.ratio, self.profile_time_s = ratio, sample.profile_time_s
        self._before_m, self._last_m = self._last_m, sample.position_m
        return sample


class LiveReference:
    """The interpolator's reference tick by tick under a live feed override (the node and the engine call this).

    Parameters
    ----------
    program : Program
    limits : AxisLimits
        The machine's limits; the profile is planned with :func:`planning_limits` of them.
    interpolator_config : InterpolatorConfig
        Its ``accel_decel`` filters the follower's samples as :meth:`Interpolator.reference` does.
    config : OverrideConfig
    """

    def __init__(self, program: Program, limits: AxisLimits, interpolator_config: InterpolatorConfig,
                 config: OverrideConfig) -> None:
        self.config = config
        self.interpolator = Interpolator(program, planning_limits(limits, config), interpolator_config)
        self.follower = OverrideFollower(self.interpolator, limits, config)
        self._filter = ReferenceFilter(interpolator_config.accel_decel)
        #: The FIR jerk filter on the retimed reference (``jerk_mode`` fir), at the machine's limits.
        self.jerk_filter = None if self.interpolator.jerk_filter is None else LiveJerkFilter(limits)
        #: The filter's own clock (ns): it steps every ``jerk_filter_period_s``, whatever the ticks' period.
        self.filter_period_ns = round(interpolator_config.jerk_filter_period_s * NS_PER_S)
        self._last_ns: int | None = None
        self._clock_ns: int | None = None
        self._tick_ns = 0
        self._before: ReferenceSample | None = None
        self._at: ReferenceSample | None = None
        stream = self.interpolator._stream  # a streaming plan (window shorter than the program), else None
        planner_class = STREAM_PLANNER_CLASSES[interpolator_config.stream_planner]
        #: Plans a streaming profile ahead of the tool in a thread or a child process (None: planned whole).
        self.planner = None if stream is None else planner_class(stream, self)

    def request(self, stamp_ns: int, latest_ratio: float) -> float:
        """The ratio requested at tick ``stamp_ns``: the schedule's if there is one, else ``latest_ratio``."""
        return self.config.scheduled_ratio(ns_to_s(stamp_ns)) if self.config.has_schedule else latest_ratio

    def step(self, stamp_ns: int, requested_ratio: float) -> ReferenceSample:
        """The reference at tick ``stamp_ns`` [ns], the ratio ramping towards ``requested_ratio``.

        dt is the difference of successive stamps (the first tick starts the
        profile at rest with the ratio requested there); the sample's
        ``feed_override_ratio`` is the applied ratio.
        """
        if self.jerk_filter is None:
            sample = self._followed(stamp_ns, requested_ratio)
        else:
            sample = self._on_filter_clock(stamp_ns, requested_ratio)
        return self._filtered(ns_to_s(stamp_ns), sample)

    def _followed(self, stamp_ns: int, requested_ratio: float) -> ReferenceSample:
        """The retimed sample at ``stamp_ns`` (dt from the last one followed)."""
        if self.planner is None:
            sample = self._advance(stamp_ns, requested_ratio)
        else:  # sampled under the plan's lock; the planner hears where the tool is
            with self.planner.condition:
                sample = self._advance(stamp_ns, requested_ratio)
                self.planner.tool_at(self.follower.profile_time_s)
        self._last_ns = stamp_ns
        return sample

    def _on_filter_clock(self, stamp_ns: int, requested_ratio: float) -> ReferenceSample:
        """The jerk-filtered reference at tick ``stamp_ns``: the follower and the filter step on the filter's clock
        (every ``filter_period_ns`` from the first tick), so ticks whose period varies (a real-time graph under
        load) keep the filter's fixed period and its jerk bound; a tick between two of its steps reads the straight
        line between the two filtered samples (ticks on the clock: the samples themselves). An earlier stamp
        restarts the filter, as :class:`LiveJerkFilter` does."""
        assert self.jerk_filter is not None
        if self._clock_ns is None or stamp_ns < self._tick_ns:
            first = self.jerk_filter.step(stamp_ns, self._followed(stamp_ns, requested_ratio))
            self._clock_ns, self._tick_ns, self._before, self._at = stamp_ns, stamp_ns, first, first
            return first
        assert self._before is not None and self._at is not None
        while self._clock_ns < stamp_ns:
            self._clock_ns += self.filter_period_ns
            self._before, self._at = self._at, self.jerk_filter.step(
                self._clock_ns, self._followed(self._clock_ns, requested_ratio))
        self._tick_ns = stamp_ns
        if self._clock_ns == stamp_ns:
            return self._at
        return between(self._before, self._at, 1.0 - (self._clock_ns - stamp_ns) / self.filter_period_ns)

    def _advance(self, stamp_ns: int, requested_ratio: float) -> ReferenceSample:
        if self._last_ns is None:
            self.follower.reset(requested_ratio)
            return self.follower.advance(0.0, requested_ratio)
        return self.follower.advance(ns_to_s(stamp_ns - self._last_ns), requested_ratio)

    def _filtered(self, t_s: float, sample: ReferenceSample) -> ReferenceSample:
        """``sample`` through the acceleration/deceleration filter (unchanged for ``kind: none``)."""
        if self.interpolator.config.accel_decel.kind == "none":
            return sample
        n = len(sample.position_m)
        flat = self._filter.step(t_s, sample.position_m.tolist() + sample.velocity_m_s.tolist()
                                 + sample.acceleration_m_s2.tolist())
        return replace(sample, position_m=np.array(flat[:n]), velocity_m_s=np.array(flat[n:2 * n]),
                       acceleration_m_s2=np.array(flat[2 * n:]))


def between(before: ReferenceSample, after: ReferenceSample, share: float) -> ReferenceSample:
    """The straight line from ``before`` to ``after`` at ``share`` in [0, 1]: position, velocity and acceleration
    (the feed their velocity's norm); every other field is ``before``'s, the sample already reached."""
    velocity = before.velocity_m_s + share * (after.velocity_m_s - before.velocity_m_s)
    return replace(before, position_m=before.position_m + share * (after.position_m - before.position_m),
                   velocity_m_s=velocity, feed_m_s=float(np.linalg.norm(velocity)),
                   acceleration_m_s2=before.acceleration_m_s2 + share * (after.acceleration_m_s2
                                                                          - before.acceleration_m_s2))


def check_source(source: str, config: OverrideConfig) -> str:
    """``source`` if it is in :data:`FEED_OVERRIDE_SOURCES` and agrees with the schedule (given iff ``schedule``)."""
    if source not in FEED_OVERRIDE_SOURCES:
        raise ConfigError(f"feed_override_source must be one of {list(FEED_OVERRIDE_SOURCES)}, got {source!r}")
    if (source == "schedule") != config.has_schedule:
        raise ConfigError(f"feed_override_source {source!r} and feed_override.schedule_times_s "
                          f"{list(config.schedule_times_s)} disagree: a schedule is given iff the source is 'schedule'")
    return source


def message_ratio(requested_ratio: float, applied_ratio: float, quantum: float) -> float:
    """The ratio a ``FeedOverride`` message asks for (dimensionless; not yet checked).

    A publisher that applies its request (an override switch, the force
    regulator) states the result in ``applied_ratio``: that is taken, its
    hold (0) included, which a switch reports for a request that rounds to 0
    or below. A bare request (an operator's, ``applied_ratio`` left 0) is
    ``requested_ratio`` on the levels of ``quantum`` (0: as given), so a
    message with only ``requested_ratio`` set no longer holds the feed.
    """
    step = float(quantum) if math.isfinite(quantum) and quantum > 0.0 else 0.0
    level = float(requested_ratio)
    if step > 0.0 and math.isfinite(level):
        level = math.copysign(math.floor(abs(level) / step + 0.5) * step, level)
    if applied_ratio != 0.0 or requested_ratio == 0.0 or (step > 0.0 and not level > 0.0):
        return float(applied_ratio)
    return level


class OverrideInbox:
    """The requests the interpolator takes from the ``feed_override`` topic (each message's :func:`message_ratio`).

    With ``previous_tick`` False the request is the latest valid ratio (1
    until one arrives). With ``previous_tick`` True tick k takes the message
    stamped at tick k−1 exactly (tick 0: 1), as the engine, which steps the
    regulator after the interpolator, does; :meth:`ready` says whether it is in.
    A non-finite ratio, or one outside [0, ``max_ratio``], is refused and the last valid one held.
    """

    def __init__(self, previous_tick: bool, max_ratio: float = math.inf) -> None:
        self.previous_tick, self.max_ratio = previous_tick, float(max_ratio)
        self.latest = 1.0
        self._by_stamp: dict[int, float] = {}
        self._previous_ns: int | None = None

    def add(self, stamp_ns: int, ratio: float) -> str | None:
        """Take one message; the reason it was refused (its ratio replaced by the last valid one), else None."""
        reason = None
        if not (math.isfinite(ratio) and 0.0 <= ratio <= self.max_ratio):
            reason = (f"feed override ratio must be finite and in [0, max_ratio = {self.max_ratio:g}], got {ratio}; "
                      f"holding {self.latest:g}")
        else:
            self.latest = float(ratio)
        if self.previous_tick and (self._previous_ns is None or stamp_ns >= self._previous_ns):
            self._by_stamp[stamp_ns] = self.latest
        return reason

    @property
    def awaited_ns(self) -> int | None:
        """The stamp whose message the next tick waits for (None: it waits for none)."""
        return None if self.ready() else self._previous_ns

    def ready(self) -> bool:
        """True when the request of the next tick is known."""
        return not self.previous_tick or self._previous_ns is None or self._previous_ns in self._by_stamp

    def take(self, stamp_ns: int) -> float:
        """The request of the tick at ``stamp_ns`` (call once per tick, in order, when :meth:`ready`)."""
        if not self.previous_tick:
            return self.latest
        ratio = 1.0 if self._previous_ns is None else self._by_stamp[self._previous_ns]
        self._by_stamp = {k: v for k, v in self._by_stamp.items() if k >= stamp_ns}
        self._previous_ns = stamp_ns
        return ratio


def hold_distance_m(speed_m_s: float, deceleration_m_s2: float) -> float:
    """The path length a feed hold from ``speed_m_s`` needs at ``deceleration_m_s2`` (a bound for tests/docs)."""
    if deceleration_m_s2 <= 0.0 or not math.isfinite(deceleration_m_s2):
        raise ConfigError(f"deceleration_m_s2 must be > 0, got {deceleration_m_s2}")
    return speed_m_s * speed_m_s / (2.0 * deceleration_m_s2)
