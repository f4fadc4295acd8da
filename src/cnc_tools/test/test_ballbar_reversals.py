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


def _lost_motion(direction: str, lost_m: float, axis: str = "x", fault: Fault | None = None) -> CircleTrace:
    """The ``axis`` table following its motor (the exact circle) through a play of ``lost_m``, plus ``fault``.

    Settled against the motion at the first point; the table stands still after a reversal until the motor has
    turned back by ``lost_m`` (as the plant's backlash), then lags by ``lost_m/2`` against the motion.
    """
    exact = _trace(direction, fault)
    points = exact.points_m.copy()
    k = 0 if axis == "x" else 1
    motor = points[:, k].copy()
    table = motor[0] - np.sign(motor[1] - motor[0]) * lost_m / 2.0
    for i, m in enumerate(motor):
        table = min(max(table, m - lost_m / 2.0), m + lost_m / 2.0)
        points[i, k] = table
    return CircleTrace(points, CENTRE_M, R_M, direction)


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
def test_lost_motion_is_a_step_at_every_x_reversal_in_both_directions(step_um: float) -> None:
    """A step persists over the half-circle after the reversal: +b at each x reversal, whichever the direction."""
    d = diagnose_reversals([_lost_motion("ccw", step_um * 1e-6), _lost_motion("cw", step_um * 1e-6)])
    for direction in ("ccw", "cw"):
        for angle in (0.0, 180.0):
            _within(_one(d.reversals, direction, angle).step_um, step_um)
    for r in d.reversals:
        assert abs(r.spike_um) < 0.5, r
        if r.axis == "y":
            assert abs(r.step_um) < 0.5, r
    _within(d.backlash_x_um, step_um)
    assert abs(d.backlash_y_um) < 0.5
    ccw_only = diagnose_reversals([_lost_motion("ccw", step_um * 1e-6)])
    _within(ccw_only.backlash_x_um, step_um)
    assert abs(ccw_only.backlash_y_um) < 0.5


@pytest.mark.parametrize("direction", ["ccw", "cw"])
def test_x_lost_motion_is_an_outward_step_at_the_x_reversals(direction: str) -> None:
    """x lags its command by b/2 against its direction of motion: the halves move apart by b along x."""
    d = diagnose_reversals([_lost_motion(direction, 10e-6)])
    _within(d.backlash_x_um, 10.0)
    assert abs(d.backlash_y_um) < 0.5


def test_a_spike_that_decays_is_no_step() -> None:
    """A friction-like transient after each y reversal (outward, decaying by e every 3°) is a spike, no backlash."""
    def spikes(sign: float) -> Fault:
        def fault(deg: np.ndarray) -> np.ndarray:
            out = np.zeros_like(deg)
            for at_deg in (90.0, 270.0):
                after = sign * ((deg - at_deg + 180.0) % 360.0 - 180.0)
                out += np.where(after >= 0.0, 20e-6 * np.exp(-np.maximum(after, 0.0) / 3.0), 0.0)
            return out
        return fault

    traces = [_trace(direction, spikes(sign)) for direction, sign in (("ccw", 1.0), ("cw", -1.0))]
    d = diagnose_reversals(traces)
    _within(d.spike_y_um, 20.0)
    assert abs(d.backlash_y_um) < 0.5 and abs(d.backlash_x_um) < 0.5


def test_spike_and_step_together_are_told_apart() -> None:
    spike = _gaussian(6e-6, 181.5, sigma_deg=1.0)  # just after the reversal at 180° (ccw)
    d = diagnose_reversals([_lost_motion("ccw", 10e-6, fault=spike)], before_deg=5.0, after_deg=20.0)
    at_180 = _one(d.reversals, "ccw", 180.0)
    _within(at_180.step_um, 10.0)
    _within(at_180.spike_um, 6.0)
    _within(d.backlash_x_um, 10.0)
    assert (d.before_deg, d.after_deg) == (5.0, 20.0)


def test_motion_labels_the_axis_turning() -> None:
    d = diagnose_reversals([_trace("cw")])
    labels = {(r.axis, r.angle_deg): r.motion for r in d.reversals}
    assert labels == {("x", 0.0): "+ to -", ("x", 180.0): "- to +", ("y", 90.0): "+ to -", ("y", 270.0): "- to +"}


def test_bad_window_and_sparse_flanks_are_errors() -> None:
    with pytest.raises(ConfigError, match=r"shorter than 90 deg, got before_deg 30, after_deg 60"):
        diagnose_reversals([_trace("ccw")], before_deg=30, after_deg=60)
    with pytest.raises(ConfigError, match=r"got before_deg -1"):
        diagnose_reversals([_trace("ccw")], before_deg=-1)
    sparse = _trace("ccw")
    sparse = CircleTrace(sparse.points_m[::200], CENTRE_M, R_M, "ccw")  # 18 points, 20° apart
    with pytest.raises(ConfigError, match="flank"):
        diagnose_reversals([sparse], before_deg=0.0, after_deg=1.0)


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
