"""Ballbar-style diagnoses of circular tests from measured XY points (ROS-free).

Each trace is one measured circle: points ``p`` (N, 2) in m, the programmed
centre ``c``, radius ``R`` and direction. With ``θ`` the angle of a point about
its trace's least-squares (LS) centre, the radius about that centre minus the
LS radius is fitted by linear least squares to a Fourier series

    ΔR(θ) = a0 + Σ_{k=1..10} (A_k cos kθ + B_k sin kθ),

which tolerates non-uniform sampling. The second harmonic is an ellipse:
``B_2`` (the ``sin 2θ`` term) has its axes along ±45°, ``A_2`` (``cos 2θ``)
along 0°/90°. To first order (paper 003, Eq. 8 and the usual ballbar model):

- a position-loop lag ``τ = 1/k`` per axis gives ``ΔR = ±(v/2)(τx − τy) sin 2θ``,
  ``+`` counter-clockwise, ``−`` clockwise: the ±45° ellipse that *flips*;
- a squareness error ``α`` (x measured as ``x + α·y``) gives ``(α R / 2) sin 2θ``
  in both directions;
- scale errors ``sx, sy`` (x measured as ``(1 + sx)·x``) give
  ``R (sx − sy)/2 · cos 2θ`` in both directions.

Hence, with ``B_ccw``, ``B_cw``, ``A_ccw``, ``A_cw`` the coefficients of the
two directions: servo mismatch ``(B_ccw − B_cw)/2``, squareness
``(B_ccw + B_cw)/R`` and scale mismatch ``(A_ccw + A_cw)/R``. Cyclic error is
the amplitude ``hypot(A_k, B_k)`` of harmonics 3..10, of the mean coefficients
over the traces (a position-dependent error has the same phase in both).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, minimize

from cnc_contour_control.core.config import require_choice, require_finite, require_positive
from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.ballbar_model import DIRECTIONS as DIRECTIONS  # re-exported: the traces' directions
from cnc_tools.analysis.ballbar_model import MAX_HARMONIC as MAX_HARMONIC
from cnc_tools.analysis.ballbar_model import FloatArray as FloatArray
from cnc_tools.analysis.ballbar_model import (
    LostMotionFit,
    fit_lost_motion,
    outside_windows,
    polar,
    without_steps,
)
from cnc_tools.analysis.circular import fit_circle

#: Fewest points a trace may have.
MIN_POINTS = 16
#: Largest angular gap between consecutive points (about the programmed centre), degrees.
MAX_ANGLE_GAP_DEG = 30.0
#: Harmonic orders reported as cyclic error.
CYCLIC_HARMONICS: tuple[int, ...] = tuple(range(3, MAX_HARMONIC + 1))
#: Two programmed centres or radii this close are the same circle, m.
SAME_CIRCLE_TOLERANCE_M = 1.0e-9
UM_PER_M = 1.0e6


@dataclass(frozen=True, eq=False)
class CircleTrace:
    """One measured circle.

    Parameters
    ----------
    points_m
        (N, 2) measured XY positions, m.
    center_m
        (2,) programmed centre, m.
    radius_m
        Programmed radius, m.
    direction
        ``"cw"`` or ``"ccw"`` (a key of :data:`DIRECTIONS`).
    feed_m_s
        Programmed feed along the circle, m/s; needed only for the gain difference.
    """

    points_m: FloatArray
    center_m: tuple[float, float]
    radius_m: float
    direction: str
    feed_m_s: float | None = None

    def __post_init__(self) -> None:
        points = np.asarray(self.points_m, dtype=float)
        if points.ndim != 2 or points.shape[1] != 2:
            raise ConfigError(f"points_m must have shape (N, 2), got {points.shape}")
        if points.shape[0] < MIN_POINTS:
            raise ConfigError(f"points_m must hold at least {MIN_POINTS} points, got {points.shape[0]}")
        if not np.all(np.isfinite(points)):
            raise ConfigError(f"points_m must be finite, got {int(np.sum(~np.isfinite(points)))} non-finite values")
        center = np.asarray(self.center_m, dtype=float).reshape(-1)
        if center.shape != (2,):
            raise ConfigError(f"center_m must have 2 values, got {center.size}")
        object.__setattr__(self, "center_m", (require_finite("center_m[0]", center[0]),
                                              require_finite("center_m[1]", center[1])))
        object.__setattr__(self, "radius_m", require_positive("radius_m", self.radius_m))
        require_choice("direction", self.direction, DIRECTIONS)
        if self.feed_m_s is not None:
            object.__setattr__(self, "feed_m_s", require_positive("feed_m_s", self.feed_m_s))
        object.__setattr__(self, "points_m", points)
        _check_coverage(points, self.center_m)


@dataclass(frozen=True)
class CircleFigures:
    """What a trace's and a test's diagnosis both give, µm (see :class:`TraceDiagnosis` for how)."""

    circularity_ls_um: float
    circularity_mz_um: float
    radial_deviation_max_um: float
    radial_deviation_min_um: float
    center_offset_x_um: float
    center_offset_y_um: float


@dataclass(frozen=True)
class TraceDiagnosis(CircleFigures):
    """Diagnoses of one trace; lengths in µm.

    ``circularity_ls_um``: max − min radius about the LS circle (Kåsa fit refined by
    ``scipy.optimize.least_squares`` on the geometric residuals).
    ``circularity_mz_um``: width of the thinnest annulus holding all points
    (``scipy.optimize.minimize``, Nelder–Mead over the centre, from the LS centre).
    ``radial_deviation_max_um`` / ``_min_um``: extremes of ``|p − c| − R`` about the
    programmed centre. ``center_offset_x_um`` / ``_y_um``: LS centre minus programmed
    centre. ``ellipse_45_um`` / ``ellipse_0_um``: ``B_2`` / ``A_2`` (module docstring).
    ``harmonic_cos_um`` / ``harmonic_sin_um``: ``A_k`` / ``B_k`` for k = 1..10.
    """

    direction: str
    ellipse_45_um: float
    ellipse_0_um: float
    harmonic_cos_um: tuple[float, ...]
    harmonic_sin_um: tuple[float, ...]


@dataclass(frozen=True)
class BallbarDiagnosis(CircleFigures):
    """Diagnoses of one or two traces (see the module docstring for the model).

    Attributes
    ----------
    traces : per-trace diagnoses, in the order given.
    circularity_ls_um, circularity_mz_um : the largest over the traces, µm.
    radial_deviation_max_um, radial_deviation_min_um : extremes over the traces, µm.
    center_offset_x_um, center_offset_y_um : mean over the traces of LS centre − programmed centre, µm.
    servo_mismatch_um : ``(B_ccw − B_cw)/2``, the ±45° ellipse that flips with direction, µm.
    gain_difference_s : ``1/k_x − 1/k_y = 2·servo_mismatch / v̄``, s, with ``v̄`` the mean feed of
        the two traces: Eq. 8 to first order gives ``B_ccw = −B_cw = (v/2)(1/k_x − 1/k_y)``.
    squareness_urad : ``(B_ccw + B_cw)/R_d`` (``R_d`` the drawn radius, :func:`drawn_radius_m`), the ±45°
        ellipse common to both directions; positive
        when x reads ``x + α·y`` with ``α > 0`` (the axes close to less than 90° in the first quadrant).
    scale_mismatch_ppm : ``sx − sy = Σ A_2 / (n_traces·R_d/2)``, the 0°/90° ellipse common to the traces.
    scale_mismatch_um : the same as the mean ``A_2``, µm.
    cyclic_error_um : amplitudes of harmonics :data:`CYCLIC_HARMONICS` of the mean coefficients, µm.
    skipped : names of the fields left ``None`` and why (both directions or a feed needed).
    """

    traces: tuple[TraceDiagnosis, ...]
    servo_mismatch_um: float | None
    gain_difference_s: float | None
    squareness_urad: float | None
    scale_mismatch_ppm: float
    scale_mismatch_um: float
    cyclic_error_um: tuple[float, ...]
    skipped: tuple[str, ...]


def _check_coverage(points_m: FloatArray, center_m: tuple[float, float]) -> None:
    """Raise ConfigError unless the points go all the way round the programmed centre."""
    angle = np.sort(np.arctan2(points_m[:, 1] - center_m[1], points_m[:, 0] - center_m[0]))
    gaps = np.diff(np.concatenate((angle, [angle[0] + 2.0 * math.pi])))
    largest_deg = math.degrees(float(np.max(gaps)))
    if largest_deg > MAX_ANGLE_GAP_DEG:
        raise ConfigError(f"points_m must cover the full circle: largest angular gap must be <= "
                          f"{MAX_ANGLE_GAP_DEG} deg, got {largest_deg:.1f} deg")


def fit_circle_ls(points_m: FloatArray) -> tuple[FloatArray, float]:
    """Geometric least-squares circle: Kåsa fit refined by ``scipy.optimize.least_squares``.

    Parameters
    ----------
    points_m
        (N, 2) points, m.

    Returns
    -------
    centre (2,) and radius, m.
    """
    (cx, cy), radius = fit_circle(points_m)
    scale = max(radius, 1e-12)

    def residual(x: FloatArray) -> FloatArray:
        centre = np.array([cx, cy]) + x[:2] * scale
        return (np.hypot(*(points_m - centre).T) - radius) / scale - x[2]

    result = least_squares(residual, np.zeros(3), xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return np.array([cx, cy]) + result.x[:2] * scale, radius + result.x[2] * scale


def minimum_zone_width(points_m: FloatArray, start_m: FloatArray) -> float:
    """Width of the thinnest annulus holding ``points_m`` (N, 2), m, searched from centre ``start_m``.

    Nelder–Mead over the centre in µm about ``start_m`` (the objective ``max r − min r`` is not
    smooth); the result is never wider than the annulus about ``start_m``.
    """
    def width_um(offset_um: FloatArray) -> float:
        radii = np.hypot(*(points_m - start_m - offset_um / UM_PER_M).T)
        return float(np.ptp(radii)) * UM_PER_M

    result = minimize(width_um, np.zeros(2), method="Nelder-Mead",
                      options={"xatol": 1e-5, "fatol": 1e-7, "initial_simplex": [[0, 0], [1, 0], [0, 1]]})
    return min(float(result.fun), width_um(np.zeros(2))) / UM_PER_M


def harmonics(angle_rad: FloatArray, deviation_m: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Fourier coefficients ``A_k``, ``B_k`` (k = 1..MAX_HARMONIC) of ``deviation_m`` over ``angle_rad``, m."""
    orders = np.arange(1, MAX_HARMONIC + 1)
    phase = np.outer(angle_rad, orders)
    design = np.column_stack((np.ones_like(angle_rad), np.cos(phase), np.sin(phase)))
    coef, *_ = np.linalg.lstsq(design, deviation_m, rcond=None)
    return coef[1:MAX_HARMONIC + 1], coef[MAX_HARMONIC + 1:]


def harmonics_at(angle_rad: FloatArray, deviation_m: FloatArray, at_rad: FloatArray) -> FloatArray:
    """The Fourier series 0..MAX_HARMONIC fitted to ``deviation_m`` over ``angle_rad``, evaluated at ``at_rad``, m."""
    orders = np.arange(1, MAX_HARMONIC + 1)

    def design(angle: FloatArray) -> FloatArray:
        phase = np.outer(angle, orders)
        return np.column_stack((np.ones_like(angle), np.cos(phase), np.sin(phase)))

    coef, *_ = np.linalg.lstsq(design(angle_rad), deviation_m, rcond=None)
    return design(at_rad) @ coef


def diagnose_trace(trace: CircleTrace, steps: LostMotionFit | None = None, index: int = 0,
                   fitted: CircleTrace | None = None) -> TraceDiagnosis:
    """The per-trace diagnoses of :class:`TraceDiagnosis`.

    The circularity, radial deviation and centre are figures of every point. The harmonics are fitted to the
    radial deviation about the programmed centre of ``fitted`` (default: the trace; :func:`less_explained`)
    with the backlash steps of ``steps`` taken out, over the points outside the reversal windows
    (``steps.kept[index]``; every point outside the default windows when ``steps`` is None, no steps taken out).
    """
    points = trace.points_m
    centre, radius = fit_circle_ls(points)
    about_lsq = points - centre
    fitted = trace if fitted is None else fitted
    angle, deviation = polar(fitted)
    keep = outside_windows(angle, trace.direction) if steps is None else steps.kept[index]
    corrected = deviation if steps is None else without_steps(fitted, steps)
    cos_m, sin_m = harmonics(angle[keep], corrected[keep])
    nominal = np.hypot(*(points - np.asarray(trace.center_m)).T) - trace.radius_m
    offset = (centre - np.asarray(trace.center_m)) * UM_PER_M
    return TraceDiagnosis(
        direction=trace.direction,
        circularity_ls_um=float(np.ptp(np.hypot(*about_lsq.T))) * UM_PER_M,
        circularity_mz_um=minimum_zone_width(points, centre) * UM_PER_M,
        radial_deviation_max_um=float(np.max(nominal)) * UM_PER_M,
        radial_deviation_min_um=float(np.min(nominal)) * UM_PER_M,
        center_offset_x_um=float(offset[0]), center_offset_y_um=float(offset[1]),
        ellipse_45_um=float(sin_m[1]) * UM_PER_M, ellipse_0_um=float(cos_m[1]) * UM_PER_M,
        harmonic_cos_um=tuple(float(v) * UM_PER_M for v in cos_m),
        harmonic_sin_um=tuple(float(v) * UM_PER_M for v in sin_m))


def _check_pair(traces: Sequence[CircleTrace]) -> None:
    """Raise ConfigError unless there are one or two traces of one circle, two in opposite directions."""
    if not 1 <= len(traces) <= 2:
        raise ConfigError(f"traces must hold 1 or 2 circle traces, got {len(traces)}")
    if len(traces) == 2:
        first, second = traces
        if first.direction == second.direction:
            raise ConfigError(f"two traces must run cw and ccw, got both {first.direction!r}")
        centre_gap = math.dist(first.center_m, second.center_m)
        if centre_gap > SAME_CIRCLE_TOLERANCE_M or abs(first.radius_m - second.radius_m) > SAME_CIRCLE_TOLERANCE_M:
            raise ConfigError(f"two traces must share programmed centre and radius, got centres "
                              f"{first.center_m}, {second.center_m} and radii {first.radius_m}, {second.radius_m} m")


def drawn_radius_m(traces: Sequence[CircleTrace]) -> float:
    """The mean radius the traces draw about the programmed centre, m: an ellipse's size is relative to it
    (a circle drawn 2.5 % small by servo lag shows a squareness or scale error 2.5 % smaller)."""
    return float(np.mean(np.concatenate([np.hypot(*(t.points_m - np.asarray(t.center_m)).T) for t in traces])))


def _flipping(traces: Sequence[CircleTrace], diags: Sequence[TraceDiagnosis]) -> tuple[
        float | None, float | None, float | None, tuple[str, ...]]:
    """Servo mismatch (µm), gain difference (s), squareness (µrad) and the names skipped."""
    if len(diags) < 2:
        need = "needs both cw and ccw traces"
        return None, None, None, (f"servo_mismatch_um: {need}", f"gain_difference_s: {need}",
                                  f"squareness_urad: {need}")
    b = {d.direction: d.ellipse_45_um for d in diags}
    mismatch_um = 0.5 * (b["ccw"] - b["cw"])
    squareness_urad = (b["ccw"] + b["cw"]) / drawn_radius_m(traces)
    feeds = [t.feed_m_s for t in traces]
    if any(f is None for f in feeds):
        return mismatch_um, None, squareness_urad, ("gain_difference_s: needs feed_m_s of both traces",)
    mean_feed = 0.5 * (feeds[0] + feeds[1])  # type: ignore[operator]  # both known: checked above
    return mismatch_um, 2.0 * mismatch_um / UM_PER_M / mean_feed, squareness_urad, ()


def less_explained(traces: Sequence[CircleTrace], explained_m: Sequence[FloatArray] | None) -> list[CircleTrace]:
    """The traces with a radial deviation already explained (m, one array (N,) per trace; e.g. a fitted
    pitch error) taken out of each point's radius about the programmed centre."""
    if explained_m is None:
        return list(traces)
    out = []
    for trace, explained in zip(traces, explained_m):
        about = trace.points_m - np.asarray(trace.center_m)
        radius = np.hypot(*about.T)
        points = np.asarray(trace.center_m) + about * ((radius - explained) / radius)[:, None]
        out.append(CircleTrace(points, trace.center_m, trace.radius_m, trace.direction, trace.feed_m_s))
    return out


def diagnose_circles(traces: Sequence[CircleTrace],
                     explained_m: Sequence[FloatArray] | None = None) -> BallbarDiagnosis:
    """Ballbar diagnoses of one trace or a cw/ccw pair of the same programmed circle.

    Parameters
    ----------
    traces
        One or two :class:`CircleTrace`; two must run in opposite directions on one circle.
    explained_m
        Per trace, a radial deviation already explained (m, e.g. the fitted pitch error), taken out before the
        steps, ellipses and harmonics are fitted (:func:`less_explained`); the circularity and radial figures
        stay those of the traces.

    Returns
    -------
    BallbarDiagnosis
        Fields that need both directions (or feeds) are ``None`` and named in ``skipped``.
    """
    _check_pair(traces)
    fitted = less_explained(traces, explained_m)
    steps = fit_lost_motion(fitted)
    diags = tuple(diagnose_trace(t, steps, k, f) for k, (t, f) in enumerate(zip(traces, fitted)))
    mismatch_um, gain_s, squareness_urad, skipped = _flipping(traces, diags)
    mean_cos = np.mean([d.harmonic_cos_um for d in diags], axis=0)
    mean_sin = np.mean([d.harmonic_sin_um for d in diags], axis=0)
    scale_um = float(mean_cos[1])
    return BallbarDiagnosis(
        traces=diags,
        circularity_ls_um=max(d.circularity_ls_um for d in diags),
        circularity_mz_um=max(d.circularity_mz_um for d in diags),
        radial_deviation_max_um=max(d.radial_deviation_max_um for d in diags),
        radial_deviation_min_um=min(d.radial_deviation_min_um for d in diags),
        center_offset_x_um=float(np.mean([d.center_offset_x_um for d in diags])),
        center_offset_y_um=float(np.mean([d.center_offset_y_um for d in diags])),
        servo_mismatch_um=mismatch_um, gain_difference_s=gain_s, squareness_urad=squareness_urad,
        scale_mismatch_ppm=2.0 * scale_um / drawn_radius_m(traces), scale_mismatch_um=scale_um,
        cyclic_error_um=tuple(float(np.hypot(mean_cos[k - 1], mean_sin[k - 1])) for k in CYCLIC_HARMONICS),
        skipped=skipped)
