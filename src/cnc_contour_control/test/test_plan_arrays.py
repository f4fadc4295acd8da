"""The array planner (plan_arrays, blend_assembly, segment_batch) against the per-segment planner it replaced.

``reference_plan`` is the planner as it was before issue 13's second round,
one segment at a time: the planned segments assembled by a loop of
constructors, each segment's limits from its own ``max_abs_tangent`` /
``max_abs_curvature_per_m`` and the per-axis arc budget, the junction speeds
and the trapezoid phases by loops. The planner must agree with it to 1e-12
on short programs of every kind (lines, arcs, helices, dwells, 2 and 3 axes).
The reference also plans the arcs' speed bands (``arc_speed_bands``, combined
budget): each band's acceleration from the per-axis loop at its top speed,
junction speeds by summing band distances, each segment's peak speed by
bisection (not the planner's closed form) and one phase per band crossed.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.blending import BlendedProgram
from cnc_contour_control.motion.geometry import ArcSegment, Dwell, LineSegment, Program, Segment
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.points import MIN_LENGTH_M
from cnc_contour_control.motion.segment_tangents import junction_turns_rad
from cnc_contour_control.testing import sibling_module

_BLENDING = sibling_module(__file__, "test_blending")
LIMITS = {2: _BLENDING.LIMITS_2, 3: _BLENDING.LIMITS_3}
CONFIGS = {
    "combined 0.01 mm": InterpolatorConfig(path_tolerance_mm=0.01, arc_combined_budget=True,
                                           arc_centripetal_fraction=0.8),
    "combined 1 band": InterpolatorConfig(path_tolerance_mm=0.01, arc_combined_budget=True,
                                          arc_centripetal_fraction=0.8, arc_speed_bands=1),
    "combined 3 bands 0.1 mm": InterpolatorConfig(path_tolerance_mm=0.1, arc_combined_budget=True, arc_speed_bands=3),
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


Band = tuple[float, float, float]  # (lowest speed m/s, highest speed m/s, tangential acceleration m/s^2)


def _arc_accel(segment: ArcSegment, acceleration: np.ndarray, tangent: np.ndarray, curvature: np.ndarray,
               speed: float) -> float:
    kappa = segment.radius_m * (segment.sweep_rad / segment.length_m) ** 2
    rate = segment.radius_m * segment.sweep_rad / segment.length_m
    bounds = []
    for j, limit in enumerate(acceleration.tolist()):
        if j in segment.plane:
            split = (limit - speed ** 2 * curvature[j]) / max(tangent[j], 1e-12)
            bounds.append(max(split, math.sqrt(max(limit ** 2 - (speed ** 2 * kappa) ** 2, 0.0)) / rate, 0.0))
        elif tangent[j] > 1e-12:
            bounds.append(limit / tangent[j])
    return min(bounds) if bounds else math.inf


def reference_limits(segment: Segment, limits: AxisLimits, config: InterpolatorConfig) -> tuple[float, list[Band]]:
    """Cruise speed and speed bands of one segment, from its own methods, axis by axis."""
    velocity, acceleration = np.asarray(limits.max_velocity_m_s), np.asarray(limits.max_acceleration_m_s2)
    tangent, curvature = segment.max_abs_tangent(), segment.max_abs_curvature_per_m()
    axis_speed = _min_ratio(velocity, tangent)
    fraction = config.arc_centripetal_fraction if curvature.any() else 0.0
    centripetal = math.sqrt(_min_ratio(fraction * acceleration, curvature)) if fraction else math.inf
    speed = min(segment.feed_m_s, axis_speed, centripetal)
    if not (config.arc_combined_budget and isinstance(segment, ArcSegment)):
        return speed, [(0.0, speed, _min_ratio((1.0 - fraction) * acceleration, tangent))]
    n = config.arc_speed_bands
    edges = [speed * math.sqrt(i / n) for i in range(n + 1)]
    return speed, [(edges[i], edges[i + 1], _arc_accel(segment, acceleration, tangent, curvature, edges[i + 1]))
                   for i in range(n)]


def band_distance(bands: list[Band], low: float, high: float) -> float:
    """Distance to change speed between ``low`` and ``high`` through the bands, m."""
    return sum((min(max(high, lo), hi) ** 2 - min(max(low, lo), hi) ** 2) / (2.0 * a) for lo, hi, a in bands)


def band_reach(bands: list[Band], speed: float, length: float) -> float:
    """Speed reached from ``speed`` over ``length`` (the last band extended above the cruise speed)."""
    distance = band_distance(bands, 0.0, speed) + length
    for lo, hi, a in bands:
        if distance <= (hi ** 2 - lo ** 2) / (2.0 * a) or (lo, hi, a) == bands[-1]:
            return math.sqrt(lo ** 2 + 2.0 * a * distance)
        distance -= (hi ** 2 - lo ** 2) / (2.0 * a)
    raise AssertionError("no bands")


def reference_speeds(program: Program, plans: list[tuple[float, list[Band]]], tolerance_rad: float) -> np.ndarray:
    smooth = (junction_turns_rad(program.segments) <= tolerance_rad) & (program.junction_dwell_s[1:-1] == 0.0)
    cruise = [v for v, _ in plans]
    speeds = [0.0] + [min(cruise[k], cruise[k + 1]) if smooth[k] else 0.0 for k in range(len(cruise) - 1)] + [0.0]
    for k in range(len(plans) - 1, -1, -1):
        speeds[k] = min(speeds[k], band_reach(plans[k][1], speeds[k + 1], program.segments[k].length_m))
    for k in range(len(plans)):
        speeds[k + 1] = min(speeds[k + 1], band_reach(plans[k][1], speeds[k], program.segments[k].length_m))
    return np.array(speeds)


def peak_speed(bands: list[Band], cruise: float, length: float, entry: float, exit_: float) -> float:
    """Highest speed of a segment, by bisection on ``up + down <= length``."""
    low, high = max(entry, exit_), cruise
    if band_distance(bands, entry, high) + band_distance(bands, exit_, high) <= length:
        return high
    for _ in range(200):
        middle = 0.5 * (low + high)
        fits = band_distance(bands, entry, middle) + band_distance(bands, exit_, middle) <= length
        low, high = (middle, high) if fits else (low, middle)
    return low


def reference_phases(program: Program, plans: list[tuple[float, list[Band]]], speeds: np.ndarray) -> list[tuple]:
    """(start time, segment, s0, v0, acceleration) of every phase, and the end time last."""
    phases, t = [], 0.0
    dwell = program.junction_dwell_s
    for k, (segment, (cruise, bands)) in enumerate(zip(program.segments, plans)):
        entry, exit_ = speeds[k], speeds[k + 1]
        peak = peak_speed(bands, cruise, segment.length_m, entry, exit_)
        up, down = band_distance(bands, entry, peak), band_distance(bands, exit_, peak)
        flat = max(segment.length_m - up - down, 0.0)
        rows = [(0.0, 0.0, 0.0, dwell[k])]
        for lo, hi, a in bands:
            v0, v1 = min(max(entry, lo), hi), min(max(peak, lo), hi)
            rows.append((band_distance(bands, entry, v0), v0, a, (v1 - v0) / a))
        rows.append((up, peak, 0.0, flat / peak))
        for lo, hi, a in reversed(bands):
            v0, v1 = min(max(peak, lo), hi), min(max(exit_, lo), hi)
            rows.append((up + flat + band_distance(bands, v0, peak), v0, -a, (v0 - v1) / a))
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
    assert_allclose(interpolator.tangential_acceleration_m_s2, [bands[-1][2] for _, bands in plans],
                    rtol=1e-12, atol=0.0)
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
