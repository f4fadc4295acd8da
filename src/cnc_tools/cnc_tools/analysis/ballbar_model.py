"""Lost motion (backlash steps) beside the ellipses, with the reversal windows left out (ROS-free).

A backlash ``b`` on axis x lets the table lag the motor by ``b/2`` against
the direction of motion: the trace is shifted by ``−sign(ẋ)·b/2`` along x on
the whole half-circle between two x reversals. In the radius about the
programmed centre that is ``b·g_x(θ)`` with

    g_x = (d/2)·sign(sin θ)·cos θ,     g_y = −(d/2)·sign(cos θ)·sin θ

(``d`` = +1 counter-clockwise, −1 clockwise; ``ẋ = −d R ω sin θ``): a *step*
of ``+b`` at each reversal of that axis that stays until the next one. A
friction *spike* is a transient after the reversal that decays back.

:func:`fit_lost_motion` fits, by linear least squares over every trace at
once, the radial deviation ``|p − c| − R`` to: per trace, harmonics
0..:data:`OWN_HARMONIC` (radius, eccentricity, the two ellipses: set-up, scale,
squareness and the servo's lag, which differ between directions); with two traces, harmonics
:data:`OWN_HARMONIC` + 1..:data:`SHARED_HARMONIC` shared by both (a
position-dependent error has one phase in both directions, whereas a
backlash step flips with the direction); and ``b_x``, ``b_y`` shared by the
traces. The samples within a reversal window (from :data:`BEFORE_DEG`
before each reversal to :data:`AFTER_DEG` after it, in time) are left out, so
the spikes do not weigh on the steps. An ellipse is not only a second
harmonic: with ``A_2``, ``B_2`` its ``cos 2θ``, ``sin 2θ`` terms it has, at second
order, ``(3/(4R))·((A_2² − B_2²) cos 4θ + 2 A_2 B_2 sin 4θ)`` (0.69 µm for the
96 µm ellipse of a 10 % drive gain error at paper 003's 4000 mm/min on
R = 10 mm), a 4th harmonic that flips with the servo's ellipse and would load
on the steps; the fit is made twice, the second time with that term of the
first fit's ellipses taken out. With one trace the shared harmonics
are left out (they cannot be told apart from the steps without the second
direction).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.core.errors import ConfigError

FloatArray = NDArray[np.float64]


class CircleTrace(Protocol):
    """What the fit reads of a trace (:class:`cnc_tools.analysis.ballbar.CircleTrace`, which imports this module)."""

    @property
    def points_m(self) -> FloatArray: ...
    @property
    def center_m(self) -> tuple[float, float]: ...
    @property
    def radius_m(self) -> float: ...
    @property
    def direction(self) -> str: ...

#: Direction name -> sign of the angular velocity (a registry, not an if-chain).
DIRECTIONS: dict[str, int] = {"ccw": 1, "cw": -1}
#: Highest harmonic fitted; harmonics 3..this are the cyclic error.
MAX_HARMONIC = 10
#: Highest harmonic fitted per trace in the step fit (radius, eccentricity, ellipses).
OWN_HARMONIC = 2
#: Fits of the steps: the second and later take out each trace's ellipse's own 4th harmonic (second order).
STEP_FIT_PASSES = 2
#: Highest harmonic shared by the two directions in the step fit (a pitch error spreads past MAX_HARMONIC).
SHARED_HARMONIC = 30

#: Reversal angles (degrees, about the centre) of each plane axis (a registry).
REVERSAL_ANGLES_DEG: dict[str, tuple[float, float]] = {"x": (0.0, 180.0), "y": (90.0, 270.0)}
#: The reversal window left out of the fits: this many degrees before each reversal (in time) ...
BEFORE_DEG = 5.0
#: ... to this many after it (the friction spike lives here).
AFTER_DEG = 30.0


@dataclass(frozen=True, eq=False)
class LostMotionFit:
    """The fitted steps [m] and, per trace, the samples used (True outside every reversal window)."""

    backlash_x_m: float
    backlash_y_m: float
    kept: tuple[np.ndarray, ...]
    before_deg: float
    after_deg: float


def polar(trace: CircleTrace) -> tuple[FloatArray, FloatArray]:
    """Angle (rad) about the programmed centre and radial deviation ``|p − c| − R`` (m) of every point."""
    about = trace.points_m - np.asarray(trace.center_m)
    return np.arctan2(about[:, 1], about[:, 0]), np.hypot(*about.T) - trace.radius_m


def step_columns(angle_rad: FloatArray, direction: str) -> FloatArray:
    """(N, 2) the radial effect of a unit backlash on x and on y (module docstring), per point."""
    d = float(DIRECTIONS[direction])
    return np.column_stack((0.5 * d * np.sign(np.sin(angle_rad)) * np.cos(angle_rad),
                            -0.5 * d * np.sign(np.cos(angle_rad)) * np.sin(angle_rad)))


def after_reversal_deg(angle_rad: FloatArray, reversal_deg: float, direction: str) -> FloatArray:
    """Degrees after the reversal at ``reversal_deg`` in time order (negative before it), in [−180, 180)."""
    offset = (np.degrees(angle_rad) - reversal_deg + 180.0) % 360.0 - 180.0
    return DIRECTIONS[direction] * offset


def outside_windows(angle_rad: FloatArray, direction: str, before_deg: float = BEFORE_DEG,
                    after_deg: float = AFTER_DEG) -> np.ndarray:
    """True for the points outside every reversal window ``[−before_deg, after_deg]``."""
    keep = np.ones(angle_rad.shape, dtype=bool)
    for angles in REVERSAL_ANGLES_DEG.values():
        for reversal in angles:
            after = after_reversal_deg(angle_rad, reversal, direction)
            keep &= ~((after >= -before_deg) & (after <= after_deg))
    return keep


def _harmonic_columns(angle_rad: FloatArray, orders: Sequence[int]) -> FloatArray:
    phase = np.outer(angle_rad, np.asarray(orders, dtype=float))
    return np.column_stack((np.cos(phase), np.sin(phase)))


def fit_lost_motion(traces: Sequence[CircleTrace], before_deg: float = BEFORE_DEG,
                    after_deg: float = AFTER_DEG) -> LostMotionFit:
    """Backlash steps of x and y from one or two traces (module docstring).

    Parameters
    ----------
    traces
        One or two :class:`CircleTrace` of one circle.
    before_deg, after_deg
        The reversal window left out, degrees before and after each reversal; their sum must stay
        below 90 (the windows of the four reversals must not cover the circle).
    """
    if not (before_deg >= 0.0 and after_deg >= 0.0 and before_deg + after_deg < 90.0):
        raise ConfigError(f"the reversal window must be >= 0 on each side and shorter than 90 deg, got "
                          f"before_deg {before_deg}, after_deg {after_deg}")
    shared = tuple(range(OWN_HARMONIC + 1, SHARED_HARMONIC + 1)) if len(traces) == 2 else ()
    width = 1 + 2 * OWN_HARMONIC
    polars = [polar(trace) for trace in traces]
    kept = [outside_windows(angle, trace.direction, before_deg, after_deg)
            for trace, (angle, _) in zip(traces, polars)]
    blocks = []
    for k, (trace, (angle, _)) in enumerate(zip(traces, polars)):
        own = np.zeros((angle.size, width * len(traces)))
        own[:, width * k:width * (k + 1)] = np.column_stack(
            (np.ones_like(angle), _harmonic_columns(angle, range(1, OWN_HARMONIC + 1))))
        columns = [own, _harmonic_columns(angle, shared), step_columns(angle, trace.direction)]
        blocks.append(np.column_stack(columns)[kept[k]])
    design = np.vstack(blocks)
    fourth = [np.zeros_like(angle) for angle, _ in polars]
    for _ in range(STEP_FIT_PASSES):
        measured = np.concatenate([(d - f)[keep] for (_, d), f, keep in zip(polars, fourth, kept)])
        coef, *_ = np.linalg.lstsq(design, measured, rcond=None)
        fourth = [_ellipse_fourth(angle, coef[width * k + 2], coef[width * k + 4], trace.radius_m)
                  for k, (trace, (angle, _)) in enumerate(zip(traces, polars))]
    return LostMotionFit(float(coef[-2]), float(coef[-1]), tuple(kept), float(before_deg), float(after_deg))


def _ellipse_fourth(angle_rad: FloatArray, cos2_m: float, sin2_m: float, radius_m: float) -> FloatArray:
    """The second-order 4th harmonic (m) of the ellipse whose ``cos 2θ``, ``sin 2θ`` terms are given (module
    docstring)."""
    return 0.75 / radius_m * ((cos2_m**2 - sin2_m**2) * np.cos(4.0 * angle_rad)
                              + 2.0 * cos2_m * sin2_m * np.sin(4.0 * angle_rad))


def play_effect(angle_rad: FloatArray, direction: str, backlash_m: tuple[float, float],
                radius_m: float) -> FloatArray:
    """The radial effect (m) of a play ``backlash_m`` (x, y) on the points at ``angle_rad`` (in time order).

    Each axis's table follows its motor ``R cos θ`` (``R sin θ``) through a dead band of that width, settled
    against the motion at the first point: outside the short stall after a reversal (about ``sqrt(2b/R)``
    rad) this is :func:`step_columns` times ``b``; inside it, the table stands still while the motor turns.
    """
    d = float(DIRECTIONS[direction])
    effect = np.zeros_like(angle_rad)
    motors = (radius_m * np.cos(angle_rad), radius_m * np.sin(angle_rad))
    velocities = (-d * np.sin(angle_rad[0]), d * np.cos(angle_rad[0]))
    for motor, velocity, unit, band in zip(motors, velocities, (np.cos(angle_rad), np.sin(angle_rad)), backlash_m):
        half = 0.5 * band
        table = motor[0] - np.sign(velocity) * half
        shift = np.empty_like(motor)
        for i, m in enumerate(motor):
            table = min(max(table, m - half), m + half)
            shift[i] = table - m
        effect += shift * unit
    return effect


def without_steps(trace: CircleTrace, fit: LostMotionFit) -> FloatArray:
    """The trace's radial deviation (m) with the fitted backlash (as a play, :func:`play_effect`) taken out."""
    angle, deviation = polar(trace)
    return deviation - play_effect(angle, trace.direction, (fit.backlash_x_m, fit.backlash_y_m), trace.radius_m)
