"""Reversal spikes and backlash steps of a circular-test trace, and its polar plot (ROS-free).

On a circle about the centre, ``x = R cos θ`` reverses where ``sin θ = 0``
(θ = 0°, 180°) and ``y = R sin θ`` where ``cos θ = 0`` (θ = 90°, 270°). The
radial deviation is taken about the trace's least-squares circle
(:func:`cnc_tools.analysis.ballbar.fit_circle_ls`, so a set-up offset drops
out), the angle about its centre. Around each reversal angle ``θr``, with
``w`` the window half-width and time order given by the trace's direction:

- the *flanks* are the points ``w..2w`` before and ``w..2w`` after ``θr``
  (in time); a straight line is fitted to the deviation on each flank
  (``numpy.polyfit``) and evaluated at ``θr`` (a smooth trend such as a
  first harmonic cancels);
- ``step_um`` = after-line at ``θr`` − before-line at ``θr``: the backlash step,
  positive when the radius jumps outwards as the axis reverses;
- ``spike_um`` = the deviation inside ``±w`` minus the flank line of its side
  (before/after), the value of largest magnitude, signed (positive outwards);
- ``lateral_um`` = the lateral step: a shift ``t`` of the trace perpendicular to
  the reversing axis (along the other axis) appearing at ``θr`` adds
  ``t·sin(θ − θr)`` to the radius after it, a change of slope ``t`` per radian
  and no step (the radius alone cannot show a perpendicular shift as a step);
  ``t`` is the kink of one least-squares fit to both flanks,
  ``a + b u + c u² + s H + t u H`` (``u`` the angle after ``θr`` in time, rad,
  ``H`` 1 after it; the shared ``c u²`` takes a smooth trend's curvature),
  signed along the *other* axis's + direction.

Per axis: ``spike_*_um`` is the signed spike of largest magnitude over that
axis's reversals (all traces), ``backlash_*_um`` the mean of its steps,
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
from cnc_tools.analysis.ballbar import DIRECTIONS, UM_PER_M, BallbarDiagnosis, CircleTrace, FloatArray, fit_circle_ls

#: Reversal angles (degrees, about the centre) of each plane axis (a registry).
REVERSAL_ANGLES_DEG: dict[str, tuple[float, float]] = {"x": (0.0, 180.0), "y": (90.0, 270.0)}
#: Default half-width of the window around a reversal, degrees.
WINDOW_DEG = 10.0
#: Largest window: the flanks (out to 2w) must stay short of the next reversal.
MAX_WINDOW_DEG = 22.5
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
    """Reversals of one or more traces and the per-axis summary, µm; ``window_deg`` is ``w``."""

    window_deg: float
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


def _motion(axis: str, angle_deg: float) -> str:
    """``"+ to -"`` at the axis's maximum, ``"- to +"`` at its minimum (either direction of travel)."""
    theta = math.radians(angle_deg)
    coordinate = {"x": math.cos(theta), "y": math.sin(theta)}[axis]
    return "+ to -" if coordinate > 0 else "- to +"


def _flank_line(offset_deg: FloatArray, deviation_m: FloatArray, mask: np.ndarray, name: str,
                window_deg: float) -> np.poly1d:
    count = int(np.sum(mask))
    if count < MIN_FLANK_POINTS:
        raise ConfigError(f"window_deg: the {name} flank ({window_deg:g}..{2 * window_deg:g} deg) must hold at "
                          f"least {MIN_FLANK_POINTS} points, got {count}")
    return np.poly1d(np.polyfit(offset_deg[mask], deviation_m[mask], 1))


def reversal_at(trace: CircleTrace, axis: str, angle_deg: float, window_deg: float = WINDOW_DEG) -> Reversal:
    """The spike and step of ``trace`` at the reversal of ``axis`` at ``angle_deg`` (module docstring)."""
    angle, deviation = radial_deviation(trace)
    sign = DIRECTIONS[trace.direction]
    offset = (angle - angle_deg + 180.0) % 360.0 - 180.0
    after_deg = sign * offset  # > 0 after the reversal in time
    before = _flank_line(offset, deviation, (after_deg <= -window_deg) & (after_deg >= -2 * window_deg),
                         "before", window_deg)
    after = _flank_line(offset, deviation, (after_deg >= window_deg) & (after_deg <= 2 * window_deg),
                        "after", window_deg)
    inside = np.abs(offset) <= window_deg
    baseline = np.where(after_deg[inside] >= 0.0, after(offset[inside]), before(offset[inside]))
    excess = deviation[inside] - baseline
    spike_m = float(excess[np.argmax(np.abs(excess))]) if excess.size else 0.0
    flanks = (np.abs(after_deg) >= window_deg) & (np.abs(after_deg) <= 2 * window_deg)
    shift_m = lateral_shift(np.radians(after_deg[flanks]), deviation[flanks]) * sign
    return Reversal(trace.direction, axis, angle_deg, _motion(axis, angle_deg), spike_m * UM_PER_M,
                    float(after(0.0) - before(0.0)) * UM_PER_M,
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


def diagnose_reversals(traces: Sequence[CircleTrace], window_deg: float = WINDOW_DEG) -> ReversalDiagnosis:
    """Spikes and steps at every axis reversal of every trace, and the per-axis summary.

    Parameters
    ----------
    traces
        One or more :class:`CircleTrace` (typically a cw/ccw pair).
    window_deg
        Half-width ``w`` of the window around a reversal, degrees, in (0, 22.5]; the flanks
        span ``w..2w`` on each side.

    Returns
    -------
    ReversalDiagnosis
    """
    if not 0.0 < window_deg <= MAX_WINDOW_DEG:
        raise ConfigError(f"window_deg must be in (0, {MAX_WINDOW_DEG}], got {window_deg}")
    if not traces:
        raise ConfigError("traces must hold at least 1 circle trace, got 0")
    found = tuple(reversal_at(t, axis, a, window_deg) for t in traces
                  for axis, angles in REVERSAL_ANGLES_DEG.items() for a in angles)
    by_axis = {axis: [r for r in found if r.axis == axis] for axis in REVERSAL_ANGLES_DEG}
    return ReversalDiagnosis(
        window_deg=float(window_deg), reversals=found,
        spike_x_um=_signed_largest([r.spike_um for r in by_axis["x"]]),
        spike_y_um=_signed_largest([r.spike_um for r in by_axis["y"]]),
        backlash_x_um=float(np.mean([r.step_um for r in by_axis["x"]])),
        backlash_y_um=float(np.mean([r.step_um for r in by_axis["y"]])),
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
