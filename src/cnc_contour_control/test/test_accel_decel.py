"""Acceleration/deceleration after interpolation (paper 003 Eq. 13): the per-sample filters against lfilter."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import signal

from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.accel_decel import (
    AccelDecelConfig,
    ReferenceFilter,
    filter_coefficients,
    make_filter,
)
from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.geometry import Program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig

DT_S = 0.001


@pytest.mark.parametrize("kind, time_constant_s", [("exponential", 0.01), ("exponential", 0.0004),
                                                   ("linear", 0.016), ("linear", 0.0003), ("none", 0.0)])
def test_per_sample_step_matches_lfilter(kind: str, time_constant_s: float) -> None:
    config = AccelDecelConfig(kind, time_constant_s)
    rng = np.random.default_rng(7)
    x = np.cumsum(rng.normal(size=(400, 3)), axis=0)
    start = x[0]
    built = make_filter(config, DT_S)
    built.reset(start.tolist())
    ours = np.array([built.step(row) for row in x[1:].tolist()])
    b, a = filter_coefficients(config, DT_S)
    history = 3000  # the filter "at rest at the start": a long run-in at the start value
    padded = np.vstack([np.tile(start, (history, 1)), x[1:]])
    expected = signal.lfilter(b, a, padded, axis=0)[history:]
    assert_allclose(ours, expected, rtol=1e-12, atol=1e-12)


def test_coefficients_follow_the_time_constant() -> None:
    b, a = filter_coefficients(AccelDecelConfig("exponential", 0.02), DT_S)
    assert b[0] == pytest.approx(1.0 - math.exp(-DT_S / 0.02)) and a == [1.0, b[0] - 1.0]
    b, _ = filter_coefficients(AccelDecelConfig("linear", 0.02), DT_S)
    assert len(b) == 20 and sum(b) == pytest.approx(1.0)


@pytest.mark.parametrize("kind, divisor, t_ip_s", [("exponential", 2.0, 0.004), ("linear", 24.0, 0.02)])
def test_radius_reduction_of_eq_13(kind: str, divisor: float, t_ip_s: float) -> None:
    radius_m, feed_m_s = 0.005, 8.0 / 60.0  # R 5 mm, 8000 mm/min: ΔR in the tens of µm
    filt = ReferenceFilter(AccelDecelConfig(kind, t_ip_s))
    omega = feed_m_s / radius_m
    t = DT_S * np.arange(3000)
    circle = np.column_stack([radius_m * np.cos(omega * t), radius_m * np.sin(omega * t)])
    rows = [filt.step(tk, [*p, 0.0, 0.0, 0.0, 0.0]) for tk, p in zip(t.tolist(), circle.tolist())]
    radius = np.hypot(*np.array(rows)[2000:, :2].T)
    reduction_m = radius_m - radius.mean()
    _, response = signal.freqz(*filter_coefficients(AccelDecelConfig(kind, t_ip_s), DT_S), worN=[omega * DT_S])
    assert reduction_m == pytest.approx(radius_m * (1.0 - abs(response[0])), rel=1e-6)  # the filter's own gain
    assert reduction_m == pytest.approx(t_ip_s ** 2 * feed_m_s ** 2 / (divisor * radius_m), rel=0.05)  # Eq. 13
    assert np.ptp(radius) < 1e-3 * reduction_m  # a steady circle, smaller


def _interpolator(kind: str, t_ip_s: float) -> Interpolator:
    config = build_config(InterpolatorConfig, {"accel_decel": {"kind": kind, "time_constant_s": t_ip_s}})
    arc = ArcSegment(start_m=(0.0, 0.0), end_m=(0.0, 0.0), center_m=(0.0, 0.01), clockwise=False,
                     feed_m_s=4.0 / 60.0)
    return Interpolator(Program(name="circle", axis_names=("x", "y"), segments=(arc,)),
                        AxisLimits((1.0, 1.0), (2.0, 2.0)), config)


@pytest.mark.parametrize("kind", ["exponential", "linear"])
def test_filtered_velocity_and_acceleration_stay_consistent_with_positions(kind: str) -> None:
    interpolator = _interpolator(kind, 0.01)
    stamps_ns = np.arange(1500, dtype=np.int64) * 1_000_000
    ref = interpolator.reference_array(stamps_ns * 1e-9)
    raw = interpolator.sample_array(stamps_ns * 1e-9)
    assert np.max(np.abs(ref.position_m - raw.position_m)) > 1e-5  # the filter acts
    mean_v = 0.5 * (ref.velocity_m_s[1:] + ref.velocity_m_s[:-1])
    assert_allclose(np.diff(ref.position_m, axis=0) / DT_S, mean_v, atol=2e-3 * 4.0 / 60.0)
    mean_a = 0.5 * (ref.acceleration_m_s2[1:] + ref.acceleration_m_s2[:-1])
    # a step of the raw acceleration (the trapezoid's corners) costs at most about one tick's share of T_ip
    step_share = DT_S / 0.01 * np.max(np.abs(raw.acceleration_m_s2))
    assert_allclose(np.diff(ref.velocity_m_s, axis=0) / DT_S, mean_a, atol=step_share)


@pytest.mark.parametrize("kind", ["exponential", "linear", "none"])
def test_per_tick_reference_equals_the_array(kind: str) -> None:
    stamps_ns = np.arange(800, dtype=np.int64) * 1_000_000
    array = _interpolator(kind, 0.01).reference_array(stamps_ns * 1e-9)
    per_tick = _interpolator(kind, 0.01)
    rows = [per_tick.reference(int(k) * 1e-9) for k in stamps_ns]
    assert_allclose(np.array([r.position_m for r in rows]), array.position_m, rtol=0, atol=1e-15)
    assert_allclose(np.array([r.velocity_m_s for r in rows]), array.velocity_m_s, rtol=0, atol=1e-15)
    assert [r.done for r in rows] == array.done.tolist()


def test_none_passes_the_sample_itself() -> None:
    interpolator = _interpolator("none", 0.0)
    assert_allclose(interpolator.reference(0.25).position_m, interpolator.sample(0.25).position_m, rtol=0, atol=0)


def test_reset_and_an_earlier_time_restart_the_filter() -> None:
    interpolator = _interpolator("exponential", 0.05)
    first = [interpolator.reference(k * DT_S).position_m for k in range(300)]
    interpolator.reset()
    again = [interpolator.reference(k * DT_S).position_m for k in range(300)]
    assert_allclose(again, first, rtol=0, atol=0)
    restarted = interpolator.reference(0.0)
    assert_allclose(restarted.position_m, interpolator.sample(0.0).position_m, rtol=0, atol=0)


def test_a_changing_tick_period_is_refused() -> None:
    filt = ReferenceFilter(AccelDecelConfig("linear", 0.01))
    filt.step(0.0, [0.0, 0.0, 0.0])
    filt.step(0.001, [1.0, 0.0, 0.0])
    with pytest.raises(ConfigError, match="accel_decel needs a fixed tick period 1000000 ns, got 2000000 ns"):
        filt.step(0.003, [1.0, 0.0, 0.0])


@pytest.mark.parametrize("values, message", [
    ({"kind": "trapezoid"}, r"accel_decel.kind must be one of \['exponential', 'linear', 'none'\], got 'trapezoid'"),
    ({"kind": "exponential", "time_constant_s": 0.0}, r"accel_decel.time_constant_s must be > 0 for kind "
                                                      r"'exponential', got 0.0"),
    ({"kind": "linear", "time_constant_s": 11.0}, r"accel_decel.time_constant_s must be in \[0.0, 10.0\], got 11.0"),
])
def test_bad_config_is_refused(values: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        build_config(InterpolatorConfig, {"accel_decel": values})
