"""``look_ahead_segments``: junction speeds planned over a window of segments with a stop at its end."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.plan_arrays import look_ahead_caps_m_s
from cnc_contour_control.testing import sibling_module

_BLENDING = sibling_module(__file__, "test_blending")
CONFIGS = {"split": InterpolatorConfig(path_tolerance_mm=0.01),
           "combined, bands": InterpolatorConfig(path_tolerance_mm=0.01, arc_combined_budget=True,
                                                 arc_centripetal_fraction=0.8)}
#: Braking from 1300 mm/min at 250 mm/s^2 takes 0.94 mm: about 27 sides of the 3600-gon (R 20 mm, 35 µm sides),
#: 3 of the 360-gon (two planned segments each), under one of lines-and-arcs' 3 mm lines; each program's window
#: (planned segments) is longer than that, and 4 is shorter on the 3600-gon.
PROGRAMS = {"3600-gon": (lambda: _BLENDING.polygon(3600), 120), "360-gon": (lambda: _BLENDING.polygon(360), 20),
            "lines-and-arcs": (_BLENDING.lines_and_arcs, 4)}


@pytest.mark.parametrize("config_name", list(CONFIGS))
@pytest.mark.parametrize("program_name", list(PROGRAMS))
def test_a_window_longer_than_the_braking_distance_plans_the_same(program_name: str, config_name: str) -> None:
    (make, window), config = PROGRAMS[program_name], CONFIGS[config_name]
    program = make()
    whole = Interpolator(program, _BLENDING.LIMITS_2, config)
    windowed = Interpolator(program, _BLENDING.LIMITS_2, dataclasses.replace(config, look_ahead_segments=window))
    caps = look_ahead_caps_m_s(whole.speed_bands.accel_m_s2[:, -1],
                               [s.length_m for s in whole.program.segments], window)
    assert np.isfinite(caps).any()  # the window is shorter than the program: its caps are in force
    assert_allclose(windowed.junction_speeds_m_s, whole.junction_speeds_m_s, rtol=1e-12, atol=0.0)
    assert windowed.duration_s == pytest.approx(whole.duration_s, rel=1e-12)


@pytest.mark.parametrize("config_name", list(CONFIGS))
def test_a_short_window_slows_down_within_the_limits(config_name: str) -> None:
    program, config, window = _BLENDING.polygon(3600), CONFIGS[config_name], 4
    whole = Interpolator(program, _BLENDING.LIMITS_2, config)
    short = Interpolator(program, _BLENDING.LIMITS_2, dataclasses.replace(config, look_ahead_segments=window))
    assert short.duration_s > 1.2 * whole.duration_s
    assert np.all(short.junction_speeds_m_s <= whole.junction_speeds_m_s * (1 + 1e-12))
    lengths = np.array([s.length_m for s in short.program.segments])
    reach = 2.0 * short.speed_bands.accel_m_s2[:, -1] * lengths
    n = lengths.size
    for j in range(0, n - window + 1, 97):  # from every junction, a stop within the window's segments
        assert short.junction_speeds_m_s[j] ** 2 <= reach[j:j + window].sum() * (1 + 1e-12)
    _BLENDING.check_limits(short, dt_s=5e-4)


@pytest.mark.parametrize(("value", "message"), [
    (0, r"look_ahead_segments must be in \[1(\.0)?, 1000000000(\.0)?\], got 0"),
    (-3, r"look_ahead_segments must be in \[1(\.0)?, 1000000000(\.0)?\], got -3"),
    (2.5, "look_ahead_segments must be a whole number, got 2.5")])
def test_bad_look_ahead_is_refused_naming_the_option(value: float, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        InterpolatorConfig(look_ahead_segments=value)
