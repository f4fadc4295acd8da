"""Ballbar diagnoses on exact synthetic circles, each with one known fault."""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.ballbar import (
    CYCLIC_HARMONICS,
    BallbarDiagnosis,
    CircleTrace,
    diagnose_circles,
    fit_circle_ls,
    minimum_zone_width,
)

R_M = 0.05
CENTRE_M = (0.1, -0.02)
N = 720
FEED_M_S = 1000.0 / 60000.0  # 1000 mm/min
#: Residuals of an exact fault model the diagnosis must leave: fit and float round-off, µm.
ROUND_OFF_UM = 1e-3

Distort = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def _trace(direction: str, distort: Distort | None = None, radius_m: float = R_M) -> CircleTrace:
    """A trace on the programmed circle, time ``t`` = arc angle / ω; ``distort(x, y)`` relative to the centre."""
    sign = 1.0 if direction == "ccw" else -1.0
    theta = sign * np.linspace(0.0, 2.0 * math.pi, N, endpoint=False)
    x, y = radius_m * np.cos(theta), radius_m * np.sin(theta)
    if distort is not None:
        x, y = distort(x, y)
    return CircleTrace(np.column_stack((x + CENTRE_M[0], y + CENTRE_M[1])), CENTRE_M, radius_m, direction, FEED_M_S)


def _pair(distort: Distort | None = None) -> BallbarDiagnosis:
    return diagnose_circles([_trace("ccw", distort), _trace("cw", distort)])


def _within(measured: float, injected: float, tol_abs: float) -> None:
    """The brief's bound: within 5 % or ``tol_abs`` (0.5 µm in the quantity's unit), whichever is larger."""
    assert abs(measured - injected) <= max(0.05 * abs(injected), tol_abs), (measured, injected)


def _others_zero(d: BallbarDiagnosis, *, keep: set[str], bound: float = ROUND_OFF_UM) -> None:
    """Every fault quantity not in ``keep`` is below ``bound`` (µm, or µm per R for angles and ppm)."""
    per_r = bound / R_M  # an angle or ratio whose ellipse is ``bound`` µm at R
    quantities = {"servo": (d.servo_mismatch_um, bound), "squareness": (d.squareness_urad, per_r),
                  "scale": (d.scale_mismatch_ppm, per_r), "centre_x": (d.center_offset_x_um, bound),
                  "centre_y": (d.center_offset_y_um, bound), "cyclic": (max(d.cyclic_error_um), bound)}
    for name, (value, limit) in quantities.items():
        if name not in keep:
            assert abs(value) <= limit, (name, value, limit)


def test_perfect_circle_has_no_fault() -> None:
    d = _pair()
    _others_zero(d, keep=set())
    assert d.circularity_ls_um < ROUND_OFF_UM and d.circularity_mz_um < ROUND_OFF_UM
    assert abs(d.radial_deviation_max_um) < ROUND_OFF_UM and abs(d.radial_deviation_min_um) < ROUND_OFF_UM
    assert d.skipped == ()


def test_squareness() -> None:
    alpha = 200e-6  # x reads x + α·y
    d = _pair(lambda x, y: (x + alpha * y, y))
    _within(d.squareness_urad, alpha * 1e6, 0.5 / R_M)
    # x + α·y adds (R α²/2) sin²θ to r: a cos 2θ term of order R α², the bound on the others.
    _others_zero(d, keep={"squareness"}, bound=max(ROUND_OFF_UM, R_M * alpha**2 * 1e6))
    # An ellipse of half-axis difference α·R: both circularities are α·R (second order in α aside).
    _within(d.circularity_ls_um, alpha * R_M * 1e6, 0.5)
    _within(d.circularity_mz_um, alpha * R_M * 1e6, 0.5)


def test_scale_mismatch() -> None:
    sx, sy = 150e-6, -50e-6
    d = _pair(lambda x, y: ((1 + sx) * x, (1 + sy) * y))
    _within(d.scale_mismatch_ppm, (sx - sy) * 1e6, 0.5 / R_M)
    _within(d.scale_mismatch_um, (sx - sy) * R_M / 2 * 1e6, 0.5)
    _others_zero(d, keep={"scale"})


def test_servo_mismatch_from_a_lag_in_x() -> None:
    """x lags by τ (x(t) = x_ref(t − τ)), y does not: the ±45° ellipse flips and gives 1/k_x − 1/k_y = τ."""
    tau_s = 2e-3
    omega = FEED_M_S / R_M

    def lag_x(x: np.ndarray, y: np.ndarray, sign: float) -> tuple[np.ndarray, np.ndarray]:
        theta = np.arctan2(y, x)
        return R_M * np.cos(theta - sign * omega * tau_s), y

    d = diagnose_circles([_trace("ccw", lambda x, y: lag_x(x, y, 1.0)), _trace("cw", lambda x, y: lag_x(x, y, -1.0))])
    _within(d.servo_mismatch_um, FEED_M_S / 2 * tau_s * 1e6, 0.5)
    assert d.gain_difference_s == pytest.approx(tau_s, rel=0.01)
    # Points (R cos(θ − a), R sin θ) lie on an ellipse symmetric about the 45° line: no 0°/90° term.
    # The radius of an ellipse of amplitude e has harmonics 4, 6, ... of order e²/R: the bound.
    ellipse_um = FEED_M_S / 2 * tau_s * 1e6
    _others_zero(d, keep={"servo"}, bound=max(ROUND_OFF_UM, ellipse_um**2 / (R_M * 1e6)))


def test_centre_offset() -> None:
    dx_m, dy_m = 7e-6, -4e-6
    d = _pair(lambda x, y: (x + dx_m, y + dy_m))
    _within(d.center_offset_x_um, 7.0, 0.5)
    _within(d.center_offset_y_um, -4.0, 0.5)
    _within(d.radial_deviation_max_um, math.hypot(7.0, 4.0), 0.5)
    _within(d.radial_deviation_min_um, -math.hypot(7.0, 4.0), 0.5)
    _others_zero(d, keep={"centre_x", "centre_y"})
    assert d.circularity_ls_um < ROUND_OFF_UM


def test_fifth_harmonic_cyclic_error() -> None:
    amplitude_m = 2e-6

    def wave(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta = np.arctan2(y, x)
        r = R_M + amplitude_m * np.cos(5 * theta + 0.3)
        return r * np.cos(theta), r * np.sin(theta)

    d = _pair(wave)
    cyclic = dict(zip(CYCLIC_HARMONICS, d.cyclic_error_um))
    _within(cyclic.pop(5), 2.0, 0.5)
    assert max(cyclic.values()) < ROUND_OFF_UM
    _within(d.circularity_ls_um, 4.0, 0.5)
    _others_zero(d, keep={"cyclic"})


def test_minimum_zone_is_never_wider_than_least_squares() -> None:
    rng = np.random.default_rng(3)
    trace = _trace("ccw", lambda x, y: (x + rng.normal(0, 1e-6, x.size), y + rng.normal(0, 1e-6, y.size)))
    d = diagnose_circles([trace])
    assert d.circularity_mz_um <= d.circularity_ls_um + 1e-9
    centre, _ = fit_circle_ls(trace.points_m)
    assert minimum_zone_width(trace.points_m, centre) * 1e6 == pytest.approx(d.circularity_mz_um)


def test_one_trace_skips_what_needs_both_directions() -> None:
    d = diagnose_circles([_trace("ccw")])
    assert d.servo_mismatch_um is None and d.squareness_urad is None and d.gain_difference_s is None
    assert any(s.startswith("servo_mismatch_um") for s in d.skipped)


@pytest.mark.parametrize(("make", "needle"), [
    (lambda: CircleTrace(np.zeros((10, 2)), (0, 0), 1.0, "cw"), "at least 16"),
    (lambda: CircleTrace(np.full((32, 2), np.nan), (0, 0), 1.0, "cw"), "finite"),
    (lambda: _trace("ccw", radius_m=0.0), "radius_m must be > 0"),
    (lambda: _trace("ccw", radius_m=-1.0), "radius_m must be > 0"),
    (lambda: CircleTrace(np.zeros((32, 3)), (0, 0), 1.0, "cw"), "shape (N, 2)"),
    (lambda: CircleTrace(_trace("ccw").points_m, CENTRE_M, R_M, "up"), "direction"),
    (lambda: CircleTrace(_trace("ccw").points_m[:N // 2], CENTRE_M, R_M, "ccw"), "full circle"),
    (lambda: diagnose_circles([_trace("ccw"), _trace("ccw")]), "cw and ccw"),
    (lambda: diagnose_circles([]), "1 or 2"),
])
def test_bad_input_names_the_problem(make: Callable[[], object], needle: str) -> None:
    with pytest.raises(ConfigError, match=None) as err:
        make()
    assert needle in str(err.value)


def _near(theta: np.ndarray, at_rad: float) -> np.ndarray:
    """1 where ``theta`` is within 3° of ``at_rad``, else 0."""
    return (np.abs(np.angle(np.exp(1j * (theta - at_rad)))) < math.radians(3.0)).astype(float)


def _bump_and_dip(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """+3 µm over ±3° at 0°, −3 µm over ±3° at 90°: a centre moved toward (+x, −y) narrows the zone to ~3.5 µm."""
    theta = np.arctan2(y, x)
    r = R_M + 3e-6 * _near(theta, 0.0) - 3e-6 * _near(theta, math.pi / 2)
    return r * np.cos(theta), r * np.sin(theta)


def test_minimum_zone_beats_a_grid_search_over_centres() -> None:
    trace = _trace("ccw", _bump_and_dip)
    d = diagnose_circles([trace])
    centre, _ = fit_circle_ls(trace.points_m)
    offsets_m = np.linspace(-3e-6, 3e-6, 61)
    grid = np.stack(np.meshgrid(offsets_m, offsets_m), axis=-1).reshape(-1, 1, 2) + centre
    widths_um = np.ptp(np.hypot(*np.moveaxis(trace.points_m - grid, -1, 0)), axis=1) * 1e6
    assert d.circularity_mz_um < d.circularity_ls_um - 1.0
    assert d.circularity_mz_um <= float(np.min(widths_um)) + 1e-3
