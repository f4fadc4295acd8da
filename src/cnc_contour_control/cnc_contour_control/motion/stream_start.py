"""The glue between :class:`~cnc_contour_control.motion.interpolation.Interpolator` and a streaming plan
(:mod:`~cnc_contour_control.motion.plan_stream`): its settings from the planner's options, the stream started
when the window is shorter than the program, and the whole plan's attributes planned on first use.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from cnc_contour_control.motion.blending import blend_program
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.jerk_fir import FirSettings, kink_acceleration_m_s2
from cnc_contour_control.motion.jerk_stream import stream_attempts
from cnc_contour_control.motion.plan_blocks import StreamSettings
from cnc_contour_control.motion.plan_stream import StreamPlan
from cnc_contour_control.motion.points import FloatArray


def stream_settings(max_velocity_m_s: FloatArray, max_acceleration_m_s2: FloatArray, config: Any,
                    tolerance_m: float, fir: FirSettings | None = None,
                    path_tolerance_m: float = 0.0) -> StreamSettings:
    """The settings of an :class:`~cnc_contour_control.motion.interpolator_config.InterpolatorConfig` (``config``)."""
    caps: tuple[FirSettings | None, FirSettings | None] = (None, None) if fir is None else stream_attempts(fir)
    if fir is not None:  # the whole plan's accelerations (Interpolator._planning_limits)
        max_acceleration_m_s2 = kink_acceleration_m_s2(np.asarray(max_velocity_m_s, float), max_acceleration_m_s2,
                                                       fir, math.radians(config.corner_angle_tolerance_deg))
    return StreamSettings(np.asarray(max_velocity_m_s, float), np.asarray(max_acceleration_m_s2, float),
                          config.arc_centripetal_fraction, config.arc_combined_budget, config.clamp_feed,
                          config.arc_speed_bands if config.arc_combined_budget else 1, config.look_ahead_segments,
                          tolerance_m, math.radians(config.corner_angle_tolerance_deg), *caps,
                          path_tolerance_m=path_tolerance_m)


def start_stream(interpolator: Any, program: Program, limits: Any, tolerance_m: float,
                 fir: FirSettings | None = None, path_tolerance_m: float = 0.0) -> StreamPlan | None:
    """A :class:`StreamPlan` for ``interpolator`` if its window is shorter than ``program``, else None (plan whole).

    ``fir`` (``jerk_mode`` fir's filter) streams the plan before the filter (:mod:`~cnc_contour_control.motion.
    jerk_stream`), its chunks checked against ``path_tolerance_m`` (m, P).

    Hands the interpolator the stream's growing lists as its sampling views (``_view``: segments, path starts;
    ``_phase_*``), so that its :meth:`sample` reads what is committed so far.
    """
    config = interpolator.config
    if config.look_ahead_segments >= len(program.segments):
        return None
    stream = StreamPlan(program, stream_settings(limits.max_velocity_m_s, limits.max_acceleration_m_s2, config,
                                                 tolerance_m, fir, path_tolerance_m))
    if stream.settings.fir is not None:  # the filter the interpolator samples with: the stream's caps
        interpolator.__dict__["_fir"] = stream.settings.fir
    interpolator.__dict__.update({"_view": stream, "_phase_start_s": stream.start_s, "_phase_s0_m": stream.s0_m,
                                  "_phase_v0_m_s": stream.v0_m_s, "_phase_accel_m_s2": stream.accel_m_s2,
                                  "_phase_segment": stream.segment})
    return stream


def whole_plan(interpolator: Any, name: str) -> dict[str, object]:
    """The attributes of a streaming ``interpolator`` that need the whole plan, for attribute ``name``.

    ``program`` and ``blended``: the whole program blended at once (the same segments as the stream's);
    the profile's arrays (``duration_s``, ``junction_speeds_m_s``, ...): the stream planned to the end.

    Raises
    ------
    AttributeError
        If ``name`` is none of them.
    """
    stream: StreamPlan = interpolator.__dict__["_stream"]
    if name in ("program", "blended"):
        settings = stream.settings
        blended = blend_program(interpolator.programmed_program, settings.tolerance_m, settings.corner_rad,
                                settings.corner_limits)
        return {"blended": blended, "program": blended.planned}
    fir = stream.settings.fir
    if name in ("duration_s", "_end_point_m", "_plan_end_s"):  # what the end's sample needs, also after forgetting
        duration_s = stream.finish()
        last = stream.segments[-1]
        return {"duration_s": duration_s + (0.0 if fir is None else fir.window_s), "_plan_end_s": duration_s,
                "_end_point_m": last.point(last.length_m)}
    if name in ("_phases", "junction_speeds_m_s", "cruise_speed_m_s", "tangential_acceleration_m_s2",
                "speed_bands"):
        arrays = stream.whole()
        arrays["_plan_end_s"] = arrays["duration_s"]
        arrays["duration_s"] = stream.planned_until_s + (0.0 if fir is None else fir.window_s)
        return arrays
    raise AttributeError(f"{type(interpolator).__name__!r} object has no attribute {name!r}")
