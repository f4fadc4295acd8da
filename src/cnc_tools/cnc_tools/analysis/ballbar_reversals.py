"""Reversal spikes and backlash steps of a circular-test trace, and its polar plot (ROS-free).

On a circle about the centre, ``x = R cos θ`` reverses where ``sin θ = 0``
(θ = 0°, 180°) and ``y = R sin θ`` where ``cos θ = 0`` (θ = 90°, 270°).
A reversal shows two different things (:mod:`cnc_tools.analysis.ballbar_model`):

- a **backlash step**: the trace offset along the reversing axis by ``b/2``
  against the direction of motion, on the whole half-circle up to the next
  reversal of that axis. ``backlash_*_um`` are the steps ``b_x``, ``b_y`` of
  :func:`~cnc_tools.analysis.ballbar_model.fit_lost_motion`, fitted beside the
  eccentricity and the ellipses (so a gain mismatch does not leak into them),
  outside the reversal windows;
- a **spike**: a transient (friction, stick-slip) after the reversal that
  decays back. The *residual* is the radial deviation minus the whole fitted
  model (the steps, and each trace's harmonics 0..10 fitted outside the
  windows); ``spike_um`` is its signed value of largest magnitude within the
  window from ``before_deg`` before to ``after_deg`` after the reversal in time.

``step_um`` of one reversal is the local step: ``b`` of its axis plus the
least-squares coefficient of that axis's step shape fitted to the residual on
the flanks (:data:`FLANK_DEG` just outside the window, each side), so one
reversal whose step differs from the others shows it.

``lateral_um`` = the lateral step: a shift ``t`` of the trace perpendicular to
the reversing axis (along the other axis) appearing at ``θr`` adds
``t·sin(θ − θr)`` to the radius after it, a change of slope ``t`` per radian
and no step (the radius alone cannot show a perpendicular shift as a step);
``t`` is the kink of one least-squares fit to both flanks
(:data:`LATERAL_WINDOW_DEG`..2× that, of the deviation about the LS circle with
the steps taken out), ``a + b u + c u² + s H + t u H`` (``u`` the angle after
``θr`` in time, rad, ``H`` 1 after it; the shared ``c u²`` takes a smooth
trend's curvature), signed along the *other* axis's + direction.

Per axis: ``spike_*_um`` is the signed spike of largest magnitude over that
axis's reversals (all traces), ``backlash_*_um`` the fitted step,
``lateral_*_um`` the mean of its lateral steps times the motion's sign (+1 at
"+ to -", −1 at "- to +": a play that follows the reversing axis's direction
of force has one sign).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.ballbar import (
    DIRECTIONS,
    UM_PER_M,
    BallbarDiagnosis,
    CircleTrace,
    FloatArray,
    fit_circle_ls,
    harmonics_at,
    less_explained,
)
from cnc_tools.analysis.ballbar_model import (
    AFTER_DEG,
    BEFORE_DEG,
    REVERSAL_ANGLES_DEG,
    LostMotionFit,
    after_reversal_deg,
    fit_lost_motion,
    polar,
    step_columns,
    without_steps,
)

__all__ = ["AFTER_DEG", "BEFORE_DEG", "REVERSAL_ANGLES_DEG", "Reversal", "ReversalDiagnosis", "diagnose_reversals"]

#: Width of the flanks just outside a reversal window on which a reversal's own step is read, degrees.
FLANK_DEG = 30.0
#: Half-width of the window of the lateral step's flanks (LATERAL_WINDOW_DEG..2x), degrees.
LATERAL_WINDOW_DEG = 10.0
#: Fewest points on each flank.
MIN_FLANK_POINTS = 3


@dataclass(frozen=True)
class Reversal:
    """One axis reversal of one trace: angle in degrees, heights in µm (module docstring)."""

    direction: str
    axis: str
    angle_deg: float
    motion: str
    spike_um: float
    step_um: float
    lateral_um: float = 0.0


@dataclass(frozen=True)
class ReversalDiagnosis:
    """Reversals of one or more traces and the per-axis summary, µm; the window runs from ``before_deg``
    before each reversal to ``after_deg`` after it (in time)."""

    before_deg: float
    after_deg: float
    reversals: tuple[Reversal, ...]
    spike_x_um: float
    spike_y_um: float
    backlash_x_um: float
    backlash_y_um: float
    lateral_x_um: float = 0.0
    lateral_y_um: float = 0.0


def radial_deviation(trace: CircleTrace) -> tuple[FloatArray, FloatArray]:
    """Angle (degrees, about the LS centre) and radius minus LS radius (m) of every point."""
    centre, radius = fit_circle_ls(trace.points_m)
    about = trace.points_m - centre
    return np.degrees(np.arctan2(about[:, 1], about[:, 0])), np.hypot(*about.T) - radius


def residual(trace: CircleTrace, steps: LostMotionFit, index: int) -> FloatArray:
    """Radial deviation minus the fitted model: the steps and the trace's harmonics 0..10 (outside the windows), m."""
    angle, _ = polar(trace)
    corrected = without_steps(trace, steps)
    keep = steps.kept[index]
    return corrected - harmonics_at(angle[keep], corrected[keep], angle)


def _motion(axis: str, angle_deg: float) -> str:
    """``"+ to -"`` at the axis's maximum, ``"- to +"`` at its minimum (either direction of travel)."""
    theta = math.radians(angle_deg)
    coordinate = {"x": math.cos(theta), "y": math.sin(theta)}[axis]
    return "+ to -" if coordinate > 0 else "- to +"


def _local_step_m(trace: CircleTrace, after: FloatArray, rest: FloatArray, axis: str, steps: LostMotionFit) -> float:
    """``b`` of the axis plus the step shape's coefficient in the residual on the two flanks, m."""
    flanks = ((after >= steps.after_deg) & (after <= steps.after_deg + FLANK_DEG)) | \
        ((after <= -steps.before_deg) & (after >= -steps.before_deg - FLANK_DEG))
    for name, side in (("before", after < 0), ("after", after > 0)):
        count = int(np.sum(flanks & side))
        if count < MIN_FLANK_POINTS:
            raise ConfigError(f"the {name} flank of the {axis} reversal must hold at least {MIN_FLANK_POINTS} "
                              f"points, got {count}")
    angle, _ = polar(trace)
    shape = step_columns(angle[flanks], trace.direction)[:, 0 if axis == "x" else 1]
    extra = float(np.dot(shape, rest[flanks]) / np.dot(shape, shape))
    return (steps.backlash_x_m if axis == "x" else steps.backlash_y_m) + extra


@dataclass(frozen=True, eq=False)
class _TraceParts:
    """What every reversal of one trace reads: angle (rad) about the centre, the residual (m), and the angle (deg)
    about the LS centre with the deviation about the LS circle less the fitted steps (m)."""

    angle_rad: FloatArray
    rest_m: FloatArray
    ls_angle_deg: FloatArray
    ls_deviation_m: FloatArray


def _trace_parts(trace: CircleTrace, steps: LostMotionFit, index: int) -> _TraceParts:
    angle, _ = polar(trace)
    ls_angle, ls_deviation = radial_deviation(trace)
    ls_deviation = ls_deviation - step_columns(np.radians(ls_angle), trace.direction) @ np.array(
        [steps.backlash_x_m, steps.backlash_y_m])
    return _TraceParts(angle, residual(trace, steps, index), ls_angle, ls_deviation)


def reversal_at(trace: CircleTrace, axis: str, angle_deg: float, steps: LostMotionFit, index: int = 0,
                parts: _TraceParts | None = None) -> Reversal:
    """The spike, step and lateral step of ``trace`` at the reversal of ``axis`` at ``angle_deg`` (module docstring).

    ``parts``: the trace's :func:`_trace_parts` when the caller reads several reversals of it (made here if None).
    """
    parts = parts or _trace_parts(trace, steps, index)
    angle, rest, ls_angle, ls_deviation = parts.angle_rad, parts.rest_m, parts.ls_angle_deg, parts.ls_deviation_m
    after = after_reversal_deg(angle, angle_deg, trace.direction)
    inside = (after >= -steps.before_deg) & (after <= steps.after_deg)
    spike_m = float(rest[inside][np.argmax(np.abs(rest[inside]))]) if np.any(inside) else 0.0
    ls_after = after_reversal_deg(np.radians(ls_angle), angle_deg, trace.direction)
    w = LATERAL_WINDOW_DEG
    lateral = (np.abs(ls_after) >= w) & (np.abs(ls_after) <= 2 * w)
    shift_m = lateral_shift(np.radians(ls_after[lateral]), ls_deviation[lateral]) * DIRECTIONS[trace.direction]
    return Reversal(trace.direction, axis, angle_deg, _motion(axis, angle_deg), spike_m * UM_PER_M,
                    _local_step_m(trace, after, rest, axis, steps) * UM_PER_M,
                    shift_m * _tangent_along_other(axis, angle_deg) * UM_PER_M)


def lateral_shift(after_rad: FloatArray, deviation_m: FloatArray) -> float:
    """The kink ``t`` of the flanks' deviation (m): least squares of ``a + b u + c u² + s H + t u H``.

    ``u`` (rad) is the angle from the reversal in time order (> 0 after it), ``H`` 1 after it; the shared
    ``c u²`` takes the curvature any smooth trend has, ``s`` the step, so ``t`` is the change of slope alone.
    """
    after = (after_rad > 0.0).astype(float)
    design = np.column_stack((np.ones_like(after_rad), after_rad, after_rad**2, after, after_rad * after))
    coef, *_ = np.linalg.lstsq(design, deviation_m, rcond=None)
    return float(coef[4])


def _tangent_along_other(axis: str, angle_deg: float) -> float:
    """The component along the other axis's + direction of the ccw tangent ``(−sin θ, cos θ)`` at ``angle_deg``."""
    theta = math.radians(angle_deg)
    return round(math.cos(theta)) if axis == "x" else round(-math.sin(theta))


def _signed_largest(values: Sequence[float]) -> float:
    return float(max(values, key=abs))


def diagnose_reversals(traces: Sequence[CircleTrace], before_deg: float = BEFORE_DEG,
                       after_deg: float = AFTER_DEG,
                       explained_m: Sequence[FloatArray] | None = None) -> ReversalDiagnosis:
    """Spikes and steps at every axis reversal of every trace, and the per-axis summary.

    Parameters
    ----------
    traces
        One or two :class:`CircleTrace` of one circle (typically a cw/ccw pair).
    before_deg, after_deg
        The reversal window, degrees before and after each reversal in time (module docstring of
        :mod:`cnc_tools.analysis.ballbar_model`); left out of the fits, searched for the spike.
    explained_m
        Per trace, a radial deviation already explained (m, e.g. the fitted pitch error), taken out first
        (:func:`~cnc_tools.analysis.ballbar.less_explained`).

    Returns
    -------
    ReversalDiagnosis
    """
    if not traces:
        raise ConfigError("traces must hold at least 1 circle trace, got 0")
    traces = less_explained(traces, explained_m)
    steps = fit_lost_motion(traces, before_deg, after_deg)
    parts = [_trace_parts(t, steps, k) for k, t in enumerate(traces)]
    found = tuple(reversal_at(t, axis, a, steps, k, parts[k]) for k, t in enumerate(traces)
                  for axis, angles in REVERSAL_ANGLES_DEG.items() for a in angles)
    by_axis = {axis: [r for r in found if r.axis == axis] for axis in REVERSAL_ANGLES_DEG}
    return ReversalDiagnosis(
        before_deg=float(before_deg), after_deg=float(after_deg), reversals=found,
        spike_x_um=_signed_largest([r.spike_um for r in by_axis["x"]]),
        spike_y_um=_signed_largest([r.spike_um for r in by_axis["y"]]),
        backlash_x_um=steps.backlash_x_m * UM_PER_M, backlash_y_um=steps.backlash_y_m * UM_PER_M,
        lateral_x_um=_lateral(by_axis["x"]), lateral_y_um=_lateral(by_axis["y"]))


def _lateral(reversals: Sequence[Reversal]) -> float:
    """Mean lateral step times the motion's sign (+1 at "+ to -", −1 at "- to +")."""
    return float(np.mean([r.lateral_um * (1.0 if r.motion == "+ to -" else -1.0) for r in reversals]))


#: Colour of each direction's trace in the polar plot (a registry).
PLOT_COLOURS: dict[str, str] = {"ccw": "tab:blue", "cw": "tab:red"}


def _fmt(value: float | None, unit: str) -> str:
    return "skipped" if value is None else f"{value:.3g} {unit}"


def report_lines(diagnosis: BallbarDiagnosis, reversals: ReversalDiagnosis) -> list[str]:
    """The numbers printed beside the polar plot, like a ballbar report."""
    lines = [f"circularity (LS) {_fmt(diagnosis.circularity_ls_um, 'µm')}",
             f"circularity (MZ) {_fmt(diagnosis.circularity_mz_um, 'µm')}",
             f"servo mismatch {_fmt(diagnosis.servo_mismatch_um, 'µm')}",
             f"squareness {_fmt(diagnosis.squareness_urad, 'µrad')}",
             f"scale mismatch {_fmt(diagnosis.scale_mismatch_ppm, 'ppm')}",
             f"backlash x {_fmt(reversals.backlash_x_um, 'µm')}, y {_fmt(reversals.backlash_y_um, 'µm')}",
             f"lateral x {_fmt(reversals.lateral_x_um, 'µm')}, y {_fmt(reversals.lateral_y_um, 'µm')}"]
    lines += [f"spike {r.direction} {r.axis} {r.angle_deg:g}°: {r.spike_um:.3g} µm" for r in reversals.reversals]
    return lines


def write_polar_plot(traces: Sequence[CircleTrace], diagnosis: BallbarDiagnosis, reversals: ReversalDiagnosis,
                     path: Path, dpi: int = 120) -> Path:
    """Write a PNG: each trace's radial deviation (µm, about its LS circle) in polar form, the LS
    circle at 0 µm, the reversal angles marked, and :func:`report_lines` beside it.

    matplotlib (Agg canvas, no pyplot state) is imported here, on use.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.0, 5.5), layout="constrained")
    ax = fig.add_subplot(1, 2, 1, projection="polar")
    low = high = 0.0
    for trace in traces:
        angle_deg, deviation_m = radial_deviation(trace)
        deviation_um, order = deviation_m * UM_PER_M, np.argsort(angle_deg)
        low, high = min(low, float(np.min(deviation_um))), max(high, float(np.max(deviation_um)))
        ax.plot(np.radians(angle_deg[order]), deviation_um[order], lw=0.8,
                color=PLOT_COLOURS[trace.direction], label=trace.direction)
    span = max(high - low, 1e-3)
    ax.plot(np.linspace(0.0, 2.0 * math.pi, 361), np.zeros(361), color="0.4", ls="--", lw=0.8, label="LS circle")
    for r in reversals.reversals:
        ax.plot(math.radians(r.angle_deg), high + 0.1 * span, "v", ms=5, color=PLOT_COLOURS[r.direction])
    ax.set_ylim(low - 0.2 * span, high + 0.2 * span)
    ax.set_rorigin(low - 1.5 * span)  # type: ignore[attr-defined]  # a PolarAxes (projection="polar")
    ax.tick_params(axis="y", labelsize="x-small")
    ax.set_title(f"R = {traces[0].radius_m * 1e3:g} mm, radial deviation [µm]", fontsize="small")
    ax.legend(loc="lower left", fontsize="x-small", bbox_to_anchor=(-0.15, -0.12))
    text = fig.add_subplot(1, 2, 2)
    text.axis("off")
    text.text(0.0, 1.0, "\n".join(report_lines(diagnosis, reversals)), va="top", family="monospace",
              fontsize="small")
    FigureCanvasAgg(fig)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path
