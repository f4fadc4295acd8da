"""Reversal spikes and backlash steps on synthetic circles with a known spike or step."""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.ballbar import CircleTrace
from cnc_tools.analysis.ballbar_reversals import Reversal, diagnose_reversals

R_M = 0.05
CENTRE_M = (0.1, -0.02)
N = 3600
#: Radial deviation added at angle θ (degrees, about the centre), m.
Fault = Callable[[np.ndarray], np.ndarray]


def _trace(direction: str, fault: Fault | None = None, offset_m: tuple[float, float] = (0.0, 0.0)) -> CircleTrace:
    sign = 1.0 if direction == "ccw" else -1.0
    theta = sign * (np.linspace(0.0, 2.0 * math.pi, N, endpoint=False) + math.pi / N)  # no point on a reversal
    radius = R_M + (fault(np.degrees(theta) % 360.0) if fault is not None else 0.0)
    points = np.column_stack((radius * np.cos(theta) + CENTRE_M[0] + offset_m[0],
                              radius * np.sin(theta) + CENTRE_M[1] + offset_m[1]))
    return CircleTrace(points, CENTRE_M, R_M, direction)


def _gaussian(height_m: float, at_deg: float, sigma_deg: float = 2.0) -> Fault:
    return lambda deg: height_m * np.exp(-0.5 * (((deg - at_deg + 180.0) % 360.0 - 180.0) / sigma_deg) ** 2)


def _sawtooth(step_m: float) -> Fault:
    """Jumps up by ``step_m`` at 0° and 180° (ccw time order) and falls back linearly over the half turn."""
    return lambda deg: step_m * (1.0 - (deg % 180.0) / 180.0)


def _within(measured: float, injected: float) -> None:
    assert abs(measured - injected) <= max(0.05 * abs(injected), 0.5), (measured, injected)


def _one(reversals: tuple[Reversal, ...], direction: str, angle_deg: float) -> Reversal:
    (found,) = [r for r in reversals if r.direction == direction and r.angle_deg == angle_deg]
    return found


def test_perfect_circle_has_no_spike_or_step() -> None:
    d = diagnose_reversals([_trace("ccw", offset_m=(20e-6, -30e-6)), _trace("cw")])
    assert len(d.reversals) == 8
    for r in d.reversals:
        assert abs(r.spike_um) < 1e-3 and abs(r.step_um) < 1e-3, r
    assert max(abs(d.spike_x_um), abs(d.spike_y_um), abs(d.backlash_x_um), abs(d.backlash_y_um)) < 1e-3


@pytest.mark.parametrize("direction", ["ccw", "cw"])
@pytest.mark.parametrize("height_um", [3.0, -12.0])
def test_gaussian_spike_at_one_y_reversal(direction: str, height_um: float) -> None:
    d = diagnose_reversals([_trace(direction, _gaussian(height_um * 1e-6, 90.0))])
    _within(_one(d.reversals, direction, 90.0).spike_um, height_um)
    _within(d.spike_y_um, height_um)
    for r in d.reversals:
        if r.angle_deg != 90.0:
            assert abs(r.spike_um) < 0.5 and abs(r.step_um) < 0.5, r
    assert abs(d.backlash_y_um) < 0.5  # a symmetric spike is no step


@pytest.mark.parametrize("step_um", [8.0, 30.0])
def test_step_at_the_x_reversals_is_the_backlash(step_um: float) -> None:
    fault = _sawtooth(step_um * 1e-6)
    d = diagnose_reversals([_trace("ccw", fault), _trace("cw", fault)])
    for angle in (0.0, 180.0):
        _within(_one(d.reversals, "ccw", angle).step_um, step_um)
        _within(_one(d.reversals, "cw", angle).step_um, -step_um)  # time runs the other way round
    for r in d.reversals:
        if r.axis == "y":
            assert abs(r.step_um) < 0.5 and abs(r.spike_um) < 0.5, r
    ccw_only = diagnose_reversals([_trace("ccw", fault)])
    _within(ccw_only.backlash_x_um, step_um)
    assert abs(ccw_only.backlash_y_um) < 0.5


@pytest.mark.parametrize("direction", ["ccw", "cw"])
def test_x_lost_motion_is_an_outward_step_at_the_x_reversals(direction: str) -> None:
    """x lags its command by b/2 against its direction of motion: the halves move apart by b along x."""
    lost_m, sign = 10e-6, 1.0 if direction == "ccw" else -1.0
    exact = _trace(direction)
    theta = np.arctan2(exact.points_m[:, 1] - CENTRE_M[1], exact.points_m[:, 0] - CENTRE_M[0])
    points = exact.points_m.copy()
    points[:, 0] -= np.sign(-sign * np.sin(theta)) * lost_m / 2.0
    d = diagnose_reversals([CircleTrace(points, CENTRE_M, R_M, direction)])
    _within(d.backlash_x_um, 10.0)
    assert abs(d.backlash_y_um) < 0.5


def test_spike_and_step_together_are_told_apart() -> None:
    spike, step = _gaussian(6e-6, 181.5, sigma_deg=1.0), _sawtooth(10e-6)  # the spike just after the reversal
    d = diagnose_reversals([_trace("ccw", lambda deg: spike(deg) + step(deg))], window_deg=8.0)
    at_180 = _one(d.reversals, "ccw", 180.0)
    _within(at_180.step_um, 10.0)
    _within(at_180.spike_um, 6.0)
    assert d.window_deg == 8.0


def test_motion_labels_the_axis_turning() -> None:
    d = diagnose_reversals([_trace("cw")])
    labels = {(r.axis, r.angle_deg): r.motion for r in d.reversals}
    assert labels == {("x", 0.0): "+ to -", ("x", 180.0): "- to +", ("y", 90.0): "+ to -", ("y", 270.0): "- to +"}


def test_bad_window_and_sparse_flanks_are_errors() -> None:
    with pytest.raises(ConfigError, match=r"window_deg must be in \(0, 22.5\], got 30"):
        diagnose_reversals([_trace("ccw")], window_deg=30)
    with pytest.raises(ConfigError, match="flank"):
        diagnose_reversals([_trace("ccw")], window_deg=0.05)


def _lateral_play_trace(direction: str, play_m: float, axis: str) -> CircleTrace:
    """The ``axis`` carriage shifted by ±play/2 along the other axis, with the sign of −(its velocity)."""
    sign = 1.0 if direction == "ccw" else -1.0
    theta = sign * (np.linspace(0.0, 2.0 * math.pi, N, endpoint=False) + math.pi / N)
    x, y = R_M * np.cos(theta), R_M * np.sin(theta)
    if axis == "x":
        y = y + 0.5 * play_m * np.sign(sign * np.sin(theta))  # ẋ = −R ω sin θ: shift +play/2 while ẋ < 0
    else:
        x = x + 0.5 * play_m * np.sign(-sign * np.cos(theta))  # ẏ = R ω cos θ: shift +play/2 while ẏ < 0
    return CircleTrace(np.column_stack((x + CENTRE_M[0], y + CENTRE_M[1])), CENTRE_M, R_M, direction)


@pytest.mark.parametrize("axis", ["x", "y"])
def test_lateral_play_is_the_perpendicular_shift_at_the_axis_reversals(axis: str) -> None:
    play_um = 8.0
    d = diagnose_reversals([_lateral_play_trace(direction, play_um * 1e-6, axis) for direction in ("ccw", "cw")])
    other = "y" if axis == "x" else "x"
    _within(getattr(d, f"lateral_{axis}_um"), play_um)
    assert abs(getattr(d, f"lateral_{other}_um")) <= 0.5
    # a perpendicular shift is no radial step: no backlash read on either axis
    assert abs(d.backlash_x_um) <= 0.5 and abs(d.backlash_y_um) <= 0.5
