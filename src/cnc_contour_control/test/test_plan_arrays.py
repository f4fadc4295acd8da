"""The array planner (plan_arrays, blend_assembly, segment_batch) against the per-segment planner it replaced.

``reference_plan`` is the planner as it was before issue 13's second round,
one segment at a time: the planned segments assembled by a loop of
constructors, each segment's limits from its own ``max_abs_tangent`` /
``max_abs_curvature_per_m`` and the per-axis arc budget, the junction speeds
and the trapezoid phases by loops. The planner must agree with it to 1e-12
on short programs of every kind (lines, arcs, helices, dwells, 2 and 3 axes).
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.blending import BlendedProgram
from cnc_contour_control.geometry import ArcSegment, Dwell, LineSegment, Program, Segment
from cnc_contour_control.interpolation import AxisLimits, Interpolator, InterpolatorConfig
from cnc_contour_control.points import MIN_LENGTH_M
from cnc_contour_control.segment_tangents import junction_turns_rad
from cnc_tools.sibling_tests import sibling_module

_BLENDING = sibling_module(__file__, "test_blending")
LIMITS = {2: _BLENDING.LIMITS_2, 3: _BLENDING.LIMITS_3}
CONFIGS = {
    "combined 0.01 mm": InterpolatorConfig(path_tolerance_mm=0.01, arc_combined_budget=True,
                                           arc_centripetal_fraction=0.8),
    "split 0.1 mm": InterpolatorConfig(path_tolerance_mm=0.1),
    "exact stop": InterpolatorConfig(),
}


def reference_segments(blended: BlendedProgram) -> list[Segment]:
    """The planned segments by the constructor loop that built them before (blending._planned_segments)."""
    program, blends = blended.programmed, {b.junction: b for b in blended.blends}
    out: list[Segment] = []
    start = program.segments[0].start_m
    for k, segment in enumerate(program.segments):
        blend, following = blends.get(k), blends.get(k + 1)
        if blend is not None:
            before = program.segments[k - 1]
            out.append(ArcSegment(start, blend.end_m, blend.center_m, blend.clockwise, blend.plane,
                                  min(before.feed_m_s, segment.feed_m_s), segment.source_line))
            start = out[-1].end_m
        piece_start = start if blend is not None else segment.start_m
        piece_end = following.start_m if following is not None else segment.end_m
        if blend is None and following is None:
            out.append(segment)
        elif isinstance(segment, ArcSegment):
            out.append(ArcSegment(piece_start, piece_end, segment.center_m, segment.clockwise, segment.plane,
                                  segment.feed_m_s, segment.source_line))
        elif np.linalg.norm(piece_end - piece_start) >= MIN_LENGTH_M \
                and np.dot(piece_end - piece_start, segment.unit_vector) > 0.0:
            out.append(LineSegment(piece_start, piece_end, segment.feed_m_s, segment.source_line))
        start = out[-1].end_m if out else start
    return out


def _min_ratio(budget: np.ndarray, usage: np.ndarray) -> float:
    used = usage > 1e-12
    return float(np.divide(budget, usage, out=np.full(budget.shape, math.inf), where=used).min())


def reference_limits(segment: Segment, limits: AxisLimits, config: InterpolatorConfig) -> tuple[float, float]:
    """Cruise speed and tangential acceleration of one segment, from its own methods, axis by axis."""
    velocity, acceleration = np.asarray(limits.max_velocity_m_s), np.asarray(limits.max_acceleration_m_s2)
    tangent, curvature = segment.max_abs_tangent(), segment.max_abs_curvature_per_m()
    axis_speed = _min_ratio(velocity, tangent)
    fraction = config.arc_centripetal_fraction if curvature.any() else 0.0
    centripetal = math.sqrt(_min_ratio(fraction * acceleration, curvature)) if fraction else math.inf
    speed = min(segment.feed_m_s, axis_speed, centripetal)
    if not (config.arc_combined_budget and isinstance(segment, ArcSegment)):
        return speed, _min_ratio((1.0 - fraction) * acceleration, tangent)
    kappa = segment.radius_m * (segment.sweep_rad / segment.length_m) ** 2
    rate = segment.radius_m * segment.sweep_rad / segment.length_m
    bounds = []
    for j, limit in enumerate(acceleration.tolist()):
        if j in segment.plane:
            split = (limit - speed ** 2 * curvature[j]) / max(tangent[j], 1e-12)
            bounds.append(max(split, math.sqrt(max(limit ** 2 - (speed ** 2 * kappa) ** 2, 0.0)) / rate, 0.0))
        elif tangent[j] > 1e-12:
            bounds.append(limit / tangent[j])
    return speed, min(bounds) if bounds else math.inf


def reference_speeds(program: Program, plans: list[tuple[float, float]], tolerance_rad: float) -> np.ndarray:
    smooth = (junction_turns_rad(program.segments) <= tolerance_rad) & (program.junction_dwell_s[1:-1] == 0.0)
    cruise = [v for v, _ in plans]
    speeds = [0.0] + [min(cruise[k], cruise[k + 1]) if smooth[k] else 0.0 for k in range(len(cruise) - 1)] + [0.0]
    reach = [2.0 * a * segment.length_m for (_, a), segment in zip(plans, program.segments)]
    for k in range(len(reach) - 1, -1, -1):
        speeds[k] = min(speeds[k], math.sqrt(speeds[k + 1] ** 2 + reach[k]))
    for k in range(len(reach)):
        speeds[k + 1] = min(speeds[k + 1], math.sqrt(speeds[k] ** 2 + reach[k]))
    return np.array(speeds)


def reference_phases(program: Program, plans: list[tuple[float, float]], speeds: np.ndarray) -> list[tuple]:
    """(start time, segment, s0, v0, acceleration) of every phase, and the end time last."""
    phases, t = [], 0.0
    dwell = program.junction_dwell_s
    for k, (segment, (cruise, accel)) in enumerate(zip(program.segments, plans)):
        entry, exit_ = speeds[k], speeds[k + 1]
        peak = max(math.sqrt(min(cruise ** 2, accel * segment.length_m + 0.5 * (entry ** 2 + exit_ ** 2))),
                   entry, exit_)
        up, down = (peak ** 2 - entry ** 2) / (2 * accel), (peak ** 2 - exit_ ** 2) / (2 * accel)
        flat = max(segment.length_m - up - down, 0.0)
        rows = [(0.0, 0.0, 0.0, dwell[k]), (0.0, entry, accel, (peak - entry) / accel), (up, peak, 0.0, flat / peak),
                (up + flat, peak, -accel, (peak - exit_) / accel)]
        for s0, v0, a, duration in rows:
            if duration > 0.0:
                phases.append((t, k, s0, v0, a))
                t += duration
    return phases + [(t + dwell[-1], len(plans) - 1, 0.0, 0.0, 0.0)]


def reference_positions(program: Program, phases: list[tuple], times_s: np.ndarray) -> np.ndarray:
    starts = np.array([p[0] for p in phases[:-1]])
    out = []
    for t in np.clip(times_s, 0.0, phases[-1][0]):
        if t >= phases[-1][0]:
            out.append(program.segments[-1].point(program.segments[-1].length_m))
            continue
        _, k, s0, v0, a = phases[max(int(np.searchsorted(starts, t, side="right")) - 1, 0)]
        dt = t - starts[max(int(np.searchsorted(starts, t, side="right")) - 1, 0)]
        out.append(program.segments[k].point(s0 + v0 * dt + 0.5 * a * dt * dt))
    return np.array(out)


def mixed_3_axes() -> Program:
    """Lines, a helix, a dwell, a 3-axis corner: what stops and what blends."""
    helix = ArcSegment([0.01, 0.0, 0.0], [0.0, 0.01, 0.002], [0.0, 0.0, 0.0], False, (0, 1), 0.02)
    return Program("mixed", ("x", "y", "z"), (
        LineSegment([0.0, 0.0, 0.0], [0.01, 0.0, 0.0], 0.02), helix,
        LineSegment([0.0, 0.01, 0.002], [-0.01, 0.01, 0.002], 0.02),
        LineSegment([-0.01, 0.01, 0.002], [-0.01, 0.0, 0.002], 0.015),
        LineSegment([-0.01, 0.0, 0.002], [-0.005, -0.004, 0.004], 0.02)), dwells=(Dwell(3, 0.2),))


PROGRAMS: dict[str, Callable[[], Program]] = {
    "36-gon": lambda: _BLENDING.polygon(36), "star": _BLENDING.star, "scallops": _BLENDING.scallops,
    "lines-and-arcs": _BLENDING.lines_and_arcs, "mixed-3-axes": mixed_3_axes,
    "tiny-polygon": lambda: _BLENDING.polygon(400, radius_m=0.01),  # lines dropped between two blends
    **{f"random-{seed}": (lambda seed=seed: _BLENDING.random_chain(
        np.random.default_rng(seed), ("x", "y", "z") if seed % 2 else ("x", "y"), (0, 2) if seed % 2 else (0, 1)))
       for seed in range(4)},
}


@pytest.mark.parametrize("config_name", list(CONFIGS))
@pytest.mark.parametrize("program_name", list(PROGRAMS))
def test_plan_equals_the_per_segment_plan(program_name: str, config_name: str) -> None:
    program, config = PROGRAMS[program_name](), CONFIGS[config_name]
    limits = LIMITS[program.n_axes]
    interpolator = Interpolator(program, limits, config)
    planned = interpolator.program.segments
    reference = reference_segments(interpolator.blended)
    assert [type(s) for s in planned] == [type(s) for s in reference]
    assert_allclose([s.start_m for s in planned], [s.start_m for s in reference], rtol=0.0, atol=1e-12)
    assert_allclose([s.length_m for s in planned], [s.length_m for s in reference], rtol=1e-12, atol=0.0)
    plans = [reference_limits(segment, limits, config) for segment in reference]
    assert_allclose(interpolator.cruise_speed_m_s, [v for v, _ in plans], rtol=1e-12, atol=0.0)
    assert_allclose(interpolator.tangential_acceleration_m_s2, [a for _, a in plans], rtol=1e-12, atol=0.0)
    speeds = reference_speeds(interpolator.program, plans, math.radians(config.corner_angle_tolerance_deg))
    assert_allclose(interpolator.junction_speeds_m_s, speeds, rtol=1e-12, atol=1e-15)
    phases = reference_phases(interpolator.program, plans, speeds)
    assert interpolator.duration_s == pytest.approx(phases[-1][0], rel=1e-12)
    times = np.linspace(-0.01, interpolator.duration_s + 0.01, 400)
    assert_allclose(interpolator.sample_array(times).position_m,
                    reference_positions(interpolator.program, phases, times), rtol=0.0, atol=1e-12)


def test_segment_limits_stays_the_per_segment_view() -> None:
    interpolator = Interpolator(_BLENDING.lines_and_arcs(), LIMITS[2], CONFIGS["combined 0.01 mm"])
    assert [(p.speed_m_s, p.acceleration_m_s2) for p in interpolator.segment_limits] == list(
        zip(interpolator.cruise_speed_m_s.tolist(), interpolator.tangential_acceleration_m_s2.tolist()))
