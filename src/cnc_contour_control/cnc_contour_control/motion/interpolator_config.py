"""The feed-profile planner's options (:class:`InterpolatorConfig`; :mod:`cnc_contour_control.motion.interpolation`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.motion.accel_decel import AccelDecelConfig

#: The jerk-limited modes (``InterpolatorConfig.jerk_mode``): ``quickest`` plans a program in both others (up to
#: ``jerk_compare_max_segments`` segments, else ``fir``) and keeps the quicker.
JERK_MODES = ("quickest", "fir", "scurve")
#: Where a streamed plan is planned on line (``InterpolatorConfig.stream_planner``).
STREAM_PLANNERS = ("process", "thread")


@dataclass(frozen=True)
class InterpolatorConfig:
    """Options of the feed-profile planner.

    Parameters
    ----------
    corner_angle_tolerance_deg : float
        Junctions whose tangent directions differ by at most this angle are
        tangent-continuous (no stop), deg, in [0, 10]. Such a junction steps
        the axis velocities by up to ``feed * angle`` (see the module notes).
    arc_centripetal_fraction : float
        Share of each axis's acceleration budget given to centripetal
        acceleration on arcs, in [0.01, 0.99]; the rest is for speed changes.
        (Near 0 or 1 one of the two budgets vanishes and an arc crawls.)
    arc_combined_budget : bool
        If True, an arc's tangential acceleration is bounded together with its
        centripetal one, ``sqrt(a_t**2 + (v**2 κ)**2) <= amax`` per axis
        (:mod:`cnc_contour_control.motion.arc_budget`), instead of only the split
        ``(1 - f) amax``: faster speed changes on arcs, same limits.
    arc_speed_bands : int
        With ``arc_combined_budget``: bands of speed on each arc, in [1, 64],
        each with the budget at its highest speed
        (:func:`cnc_contour_control.motion.arc_budget.speed_bands`), so that an arc
        speeds up and brakes harder the slower it goes. 1: one constant
        tangential acceleration per arc (the budget at its cruise speed).
    look_ahead_segments : int
        Segments the planner sees ahead of each junction, in [1, 1e9]: the
        speed there must allow a stop at the end of the last one (a look-ahead
        buffer; :func:`cnc_contour_control.motion.plan_arrays.look_ahead_caps_m_s`).
        The default (1e6) is longer than any braking distance of today's
        programs: their plan is unchanged.
    path_tolerance_mm : float
        Largest distance of a corner blend from the programmed corner, mm, in
        [0, 1000] (G64 P; :mod:`cnc_contour_control.motion.blending`). 0 plans the
        program as written; a program's own ``path_tolerance_m`` (G64 P, G61)
        takes precedence.
    clamp_feed : bool
        If True, slow a segment whose programmed feed exceeds the axis velocity
        limits; if False, refuse the program.
    accel_decel : AccelDecelConfig or Mapping
        Acceleration/deceleration after interpolation (paper 003's T_ip), applied by
        :meth:`Interpolator.reference` (:mod:`cnc_contour_control.motion.accel_decel`).
    jerk_mode : str
        With a jerk limit: ``fir`` (the plan through a moving average, :mod:`~cnc_contour_control.motion.jerk_fir`),
        ``scurve`` (:mod:`~cnc_contour_control.motion.jerk_plan`) or ``quickest`` (both, the quicker kept;
        :attr:`Interpolator.jerk_mode_used <cnc_contour_control.motion.interpolation.Interpolator>` says which).
        ``fir`` is the default: the only mode whose feed-override ramps and feed holds keep the jerk limit.
    jerk_compare_max_segments : int
        ``quickest``: programs of at most this many segments are planned in both modes, in [0, 1e9]; a longer one
        runs ``fir`` (``scurve`` crawls on dense chords and plans 3-5 times slower there).
    jerk_filter_period_s : float
        ``fir``: the filter's sample period T, s, in [1e-5, 0.1]; its jerk bound holds at every multiple of T.
    jerk_filter_tolerance_share : float
        ``fir``: share of the path tolerance left to the filter, in [0.05, 0.95] (the blends get the rest).
    stream_planner : str
        On line, where a streamed plan is planned ahead of the tool: ``process`` (a child process,
        :mod:`~cnc_contour_control.motion.plan_process`) or ``thread`` (in the node's process,
        :mod:`~cnc_contour_control.motion.plan_background`, sharing the interpreter lock with the ticks).
    """

    corner_angle_tolerance_deg: float = param(
        1.0e-4, unit="deg", low=0.0, high=10.0, read_only=True,
        description="junctions whose tangents differ by at most this angle are passed without a stop")
    arc_centripetal_fraction: float = param(
        0.8, low=0.01, high=0.99, read_only=True,
        description="share of each axis's acceleration for centripetal use on arcs (the rest changes speed)")
    arc_combined_budget: bool = param(
        True, read_only=True,
        description="bound an arc's tangential and centripetal acceleration together (faster speed changes on arcs)")
    arc_speed_bands: int = param(
        8, low=1, high=64, read_only=True,
        description="with arc_combined_budget: speed bands per arc, each with the acceleration budget at its top "
                    "speed")
    look_ahead_segments: int = param(
        1_000_000, low=1, high=1.0e9, read_only=True,
        description="segments planned ahead of each junction; the speed there allows a stop at the last one's end")
    path_tolerance_mm: float = param(
        0.0, unit="mm", low=0.0, high=1000.0, read_only=True,
        description="largest deviation of corner blends from the programmed path (G64 P; 0: no blending, the "
                    "program's G64 P / G61 overrides it)")
    clamp_feed: bool = param(
        False, read_only=True,
        description="slow down a segment whose feed exceeds the axis limits instead of refusing it")
    accel_decel: AccelDecelConfig = param(default_factory=AccelDecelConfig, read_only=True,
                                          description="acceleration/deceleration after interpolation (T_ip)")
    jerk_mode: str = param("fir", read_only=True, description="with a jerk limit: fir (moving average after the "
                           "(v, a) plan), scurve (S-curve planner) or quickest (both planned, the quicker kept)")
    jerk_compare_max_segments: int = param(
        1000, low=0, high=1.0e9, read_only=True,
        description="quickest: programs of at most this many segments are planned in both modes, longer ones run fir")
    jerk_filter_period_s: float = param(1.0e-3, unit="s", low=1.0e-5, high=0.1, read_only=True,
                                        description="fir: the jerk filter's sample period (jerk held at multiples)")
    jerk_filter_tolerance_share: float = param(0.5, low=0.05, high=0.95, read_only=True,
                                               description="fir: share of the path tolerance left to the filter")
    stream_planner: str = param("process", read_only=True,
                                description="on line, where a streamed plan (look_ahead_segments shorter than the "
                                            "program) is planned ahead of the tool: process (a child process, "
                                            "another core) or thread (in the node's process)")

    def __post_init__(self) -> None:
        if not isinstance(self.accel_decel, AccelDecelConfig):
            object.__setattr__(self, "accel_decel", build_config(AccelDecelConfig, self.accel_decel, "accel_decel"))
        check_ranges(self)
        require_choice("jerk_mode", self.jerk_mode, JERK_MODES)
        require_choice("stream_planner", self.stream_planner, STREAM_PLANNERS)
        for name in ("clamp_feed", "arc_combined_budget"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ConfigError(f"{name} must be true or false, got {getattr(self, name)!r}")
        for name in ("arc_speed_bands", "look_ahead_segments", "jerk_compare_max_segments"):
            value = getattr(self, name)
            if isinstance(value, float) and not value.is_integer():
                raise ConfigError(f"{name} must be a whole number, got {value!r}")
            object.__setattr__(self, name, int(value))
