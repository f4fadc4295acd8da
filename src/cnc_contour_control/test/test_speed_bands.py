"""Arcs' speed bands (combined budget, ``arc_speed_bands``): each band's acceleration holds over the band, the
bands approach the continuous budget, more bands are never slower, and the profile stays within the limits."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import quad

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.arc_budget import combined_tangential_m_s2, speed_bands
from cnc_contour_control.motion.geometry import ArcSegment
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.plan_arrays import SpeedBands, segment_extents
from cnc_contour_control.testing import sibling_module

_BLENDING = sibling_module(__file__, "test_blending")
ACCEL_M_S2 = np.array([0.25, 0.25, 0.4])
ARCS = {
    "quarter R 0.5 mm": ArcSegment([5e-4, 0.0, 0.0], [0.0, 5e-4, 0.0], [0.0, 0.0, 0.0], False, (0, 1), 0.02),
    "diagonal 60° R 2 mm": ArcSegment([2e-3 * math.cos(0.5), 2e-3 * math.sin(0.5), 0.0],
                                      [2e-3 * math.cos(1.55), 2e-3 * math.sin(1.55), 0.0], [0.0, 0.0, 0.0],
                                      False, (0, 1), 0.02),
    "helix R 1 mm": ArcSegment([1e-3, 0.0, 0.0], [0.0, 1e-3, 5e-4], [0.0, 0.0, 0.0], False, (0, 1), 0.02),
    "XZ half circle R 4 mm": ArcSegment([4e-3, 0.0, 0.0], [-4e-3, 0.0, 0.0], [0.0, 0.0, 0.0], True, (0, 2), 0.02),
}


def bands_of(arc: ArcSegment, cruise_m_s: float, n_bands: int) -> tuple[np.ndarray, np.ndarray]:
    extents = segment_extents([arc], 3)
    edges, accel = speed_bands(extents.kappa_per_m, extents.rate, extents.in_plane, np.array([cruise_m_s]),
                               ACCEL_M_S2, extents.tangent, extents.curvature_per_m, n_bands)
    return edges[0], accel[0]


def centripetal_cruise_m_s(arc: ArcSegment, fraction: float = 0.8) -> float:
    plane = list(arc.plane)
    return math.sqrt(np.min(fraction * ACCEL_M_S2[plane] / arc.max_abs_curvature_per_m()[plane]))


@pytest.mark.parametrize("name", list(ARCS))
def test_each_band_holds_the_budget_at_every_speed_in_it(name: str) -> None:
    arc = ARCS[name]
    cruise = centripetal_cruise_m_s(arc)
    edges, accel = bands_of(arc, cruise, 6)
    assert edges[0] == 0.0 and edges[-1] == pytest.approx(cruise, rel=1e-15)
    assert np.all(np.diff(accel) <= 0.0)  # harder the slower
    assert accel[-1] == pytest.approx(combined_tangential_m_s2(arc, cruise, ACCEL_M_S2), rel=1e-12)
    for i in range(6):
        budget = [combined_tangential_m_s2(arc, v, ACCEL_M_S2) for v in np.linspace(edges[i], edges[i + 1], 25)]
        assert accel[i] <= min(budget) * (1 + 1e-12)
        assert accel[i] == pytest.approx(budget[-1], rel=1e-12)


@pytest.mark.parametrize("name", ["quarter R 0.5 mm", "XZ half circle R 4 mm"])
def test_bands_approach_the_continuous_budget(name: str) -> None:
    """Time from rest to the cruise speed against the integral of 1 / a(v) with the budget at each speed."""
    arc = ARCS[name]
    cruise = centripetal_cruise_m_s(arc)
    exact_s = quad(lambda v: 1.0 / combined_tangential_m_s2(arc, v, ACCEL_M_S2), 0.0, cruise, limit=200)[0]
    ratios = []
    for n_bands in (1, 2, 4, 8, 16):
        edges, accel = bands_of(arc, cruise, n_bands)
        ratios.append(float(np.sum(np.diff(edges) / accel)) / exact_s)
    assert ratios[0] > 1.3  # one band: the budget at the cruise speed all the way
    assert all(r >= 1.0 - 1e-9 for r in ratios) and np.all(np.diff(ratios) < 0.0)
    assert ratios[3] < 1.04 and ratios[4] < 1.02


def test_distance_and_speed_are_inverse() -> None:
    arc = ARCS["quarter R 0.5 mm"]
    cruise = centripetal_cruise_m_s(arc)
    edges, accel = bands_of(arc, cruise, 8)
    bands = SpeedBands(np.array([edges, [0.0] * 8 + [0.02]]), np.array([accel, [0.25] * 8]))
    speeds = np.array([[0.3 * cruise, 0.013], [cruise, 0.02], [0.0, 0.0], [0.99 * cruise, 1e-4]])
    for v in speeds:
        distance = bands.distance_m(np.zeros(2), v)
        assert_allclose(bands.speed_m_s(distance), v, rtol=1e-12, atol=1e-15)
    assert bands.distance_m(np.zeros(2), np.array([0.0, 0.01]))[1] == pytest.approx(0.01 ** 2 / (2 * 0.25), rel=1e-15)


def bench_like(n_bands: int) -> InterpolatorConfig:
    return InterpolatorConfig(path_tolerance_mm=0.01, arc_combined_budget=True, arc_centripetal_fraction=0.8,
                              arc_speed_bands=n_bands)


PROGRAMS = {"scallops": _BLENDING.scallops, "lines-and-arcs": _BLENDING.lines_and_arcs,
            "36-gon": lambda: _BLENDING.polygon(36),
            "random XZ": lambda: _BLENDING.random_chain(np.random.default_rng(7), ("x", "y", "z"), (0, 2))}
#: Largest ratio of the 8-band to the 1-band cycle time (measured 0.916, 0.967, 1.000, 0.975): the scallops brake
#: into every fillet on their arcs; the 36-gon's blend arcs are all passed at their cruise speed.
GAIN = {"scallops": 0.93, "lines-and-arcs": 0.98, "36-gon": 1.0, "random XZ": 0.99}


@pytest.mark.parametrize("name", list(PROGRAMS))
def test_more_bands_are_never_slower_and_stay_within_the_limits(name: str) -> None:
    program = PROGRAMS[name]()
    limits = _BLENDING.LIMITS_3 if program.n_axes == 3 else _BLENDING.LIMITS_2
    plans = {n: Interpolator(program, limits, bench_like(n)) for n in (1, 2, 8)}
    durations = [plans[n].duration_s for n in (1, 2, 8)]
    assert durations[2] <= durations[1] * (1 + 1e-12) and durations[1] <= durations[0] * (1 + 1e-12)
    assert durations[2] <= GAIN[name] * durations[0] * (1 + 1e-12)
    assert np.all(plans[8].junction_speeds_m_s >= plans[1].junction_speeds_m_s * (1 - 1e-12))
    _BLENDING.check_limits(plans[8], dt_s=5e-4)


def test_sample_array_and_advance_agree_with_sample_on_bands() -> None:
    interpolator = Interpolator(_BLENDING.scallops(), _BLENDING.LIMITS_2, bench_like(8))
    times = np.linspace(0.0, interpolator.duration_s, 301)
    trajectory = interpolator.sample_array(times)
    samples = [interpolator.sample(t) for t in times.tolist()]
    assert_allclose(trajectory.position_m, [s.position_m for s in samples], rtol=0.0, atol=1e-15)
    assert_allclose(trajectory.acceleration_m_s2, [s.acceleration_m_s2 for s in samples], rtol=0.0, atol=1e-15)
    interpolator.reset()
    advanced = [interpolator.advance(dt) for dt in np.diff(times, prepend=0.0).tolist()]
    assert_allclose([s.position_m for s in advanced], [s.position_m for s in samples], rtol=0.0, atol=1e-12)


@pytest.mark.parametrize(("value", "message"), [(0, r"arc_speed_bands must be in \[1(\.0)?, 64(\.0)?\], got 0"),
                                                (65, r"arc_speed_bands must be in \[1(\.0)?, 64(\.0)?\], got 65"),
                                                (2.5, "arc_speed_bands must be a whole number, got 2.5")])
def test_bad_band_count_is_refused_naming_the_option(value: float, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        InterpolatorConfig(arc_speed_bands=value)
