"""Cyclic (lead-screw pitch) error of each plane axis from circular-test traces, for a known pitch (ROS-free).

A pitch error of axis ``j`` is periodic in the axis *position*, not in the
angle: ``e_j(q) = a_j sin(2π q / P_j) + b_j cos(2π q / P_j)`` with ``q`` the
absolute axis coordinate and ``P_j`` the screw's pitch. On a circle it moves
the radius by ``e_x(x) cos θ + e_y(y) sin θ`` (first order), which spreads
over many angular harmonics (a Bessel series in ``2πR/P``), so the harmonic
amplitudes of :func:`cnc_tools.analysis.ballbar.diagnose_circles` do not give
its size. Here ``a_j, b_j`` are fitted by linear least squares
(``numpy.linalg.lstsq``) to the radial deviation about the programmed centre,
``|p − c| − R``, of every trace at once, together with each trace's own
harmonics 0..:data:`LOW_HARMONIC` (radius, centre offset, ellipses: set-up and
the other faults' low orders), with the backlash steps of
:func:`~cnc_tools.analysis.ballbar_model.fit_lost_motion` taken out and the
reversal windows left out (as for the ellipses). The amplitude of axis ``j`` is
``hypot(a_j, b_j)``: the ``A`` of the plant's ``A sin(2π q/P)``.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.ballbar import UM_PER_M, CircleTrace, FloatArray
from cnc_tools.analysis.ballbar_model import fit_lost_motion, without_steps

#: Plane axis name -> (column of the trace's points, the radial projection of that axis).
PLANE_AXES: dict[str, int] = {"x": 0, "y": 1}
#: Highest angular harmonic fitted beside the pitch terms (2: centre offset and ellipses).
LOW_HARMONIC = 2
M_PER_MM = 1.0e-3


@dataclass(frozen=True)
class CyclicFit:
    """Fitted pitch error per plane axis: amplitude [µm], phase [rad] of ``sin(2π q/P + phase)``, pitch [mm]."""

    amplitude_um: Mapping[str, float]
    phase_rad: Mapping[str, float]
    pitch_mm: Mapping[str, float]
    residual_rms_um: float


def _harmonic_columns(angle: FloatArray) -> FloatArray:
    orders = np.arange(1, LOW_HARMONIC + 1)
    phase = np.outer(angle, orders)
    return np.column_stack((np.ones_like(angle), np.cos(phase), np.sin(phase)))


def _pitch_columns(trace: CircleTrace, pitch_mm: Mapping[str, float]) -> FloatArray:
    about = trace.points_m - np.asarray(trace.center_m)
    unit = about / np.hypot(*about.T)[:, None]
    columns = []
    for axis, pitch in pitch_mm.items():
        k = PLANE_AXES[axis]
        phase = 2.0 * math.pi * trace.points_m[:, k] / (pitch * M_PER_MM)
        columns += [unit[:, k] * np.sin(phase), unit[:, k] * np.cos(phase)]
    return np.column_stack(columns)


def _checked_pitches(pitch_mm: Mapping[str, float]) -> dict[str, float]:
    if not pitch_mm:
        raise ConfigError(f"pitch_mm must name at least one of {sorted(PLANE_AXES)}, got {dict(pitch_mm)!r}")
    for axis, pitch in pitch_mm.items():
        if axis not in PLANE_AXES:
            raise ConfigError(f"pitch_mm: axis must be one of {sorted(PLANE_AXES)}, got {axis!r}")
        if not (isinstance(pitch, (int, float)) and math.isfinite(pitch) and pitch > 0):
            raise ConfigError(f"pitch_mm.{axis} must be > 0, got {pitch!r}")
    return {axis: float(p) for axis, p in pitch_mm.items()}


def fit_cyclic_error(traces: Sequence[CircleTrace], pitch_mm: Mapping[str, float]) -> CyclicFit:
    """The pitch error of each axis in ``pitch_mm`` (plane axis ``"x"``/``"y"`` -> pitch, mm), module docstring.

    Parameters
    ----------
    traces
        One or more traces of one programmed circle (points in absolute machine coordinates, m).
    pitch_mm
        The screw pitch of each axis to fit, mm (> 0).
    """
    pitches = _checked_pitches(pitch_mm)
    if not traces:
        raise ConfigError("traces must hold at least 1 circle trace, got 0")
    n_low = 1 + 2 * LOW_HARMONIC
    blocks, pitch_rows, deviation = [], [], []
    steps = fit_lost_motion(traces)
    for k, trace in enumerate(traces):
        about = trace.points_m - np.asarray(trace.center_m)
        keep = steps.kept[k]
        blocks.append(_harmonic_columns(np.arctan2(about[:, 1], about[:, 0]))[keep])
        pitch_rows.append(_pitch_columns(trace, pitches)[keep])
        deviation.append(without_steps(trace, steps)[keep])
    rows = sum(b.shape[0] for b in blocks)
    design = np.zeros((rows, n_low * len(blocks) + 2 * len(pitches)))
    start = 0
    for k, (block, pitch_block) in enumerate(zip(blocks, pitch_rows)):
        design[start:start + block.shape[0], k * n_low:(k + 1) * n_low] = block
        design[start:start + block.shape[0], n_low * len(blocks):] = pitch_block
        start += block.shape[0]
    measured = np.concatenate(deviation)
    coef, *_ = np.linalg.lstsq(design, measured, rcond=None)
    ab = coef[n_low * len(blocks):].reshape(len(pitches), 2)
    residual_um = float(np.sqrt(np.mean((measured - design @ coef) ** 2))) * UM_PER_M
    return CyclicFit(amplitude_um={axis: float(np.hypot(*ab[i])) * UM_PER_M for i, axis in enumerate(pitches)},
                     phase_rad={axis: float(math.atan2(ab[i, 1], ab[i, 0])) for i, axis in enumerate(pitches)},
                     pitch_mm=pitches, residual_rms_um=residual_um)


def pitch_error_m(trace: CircleTrace, fit: CyclicFit) -> FloatArray:
    """The radial deviation (N,) [m] the fitted pitch errors give at the trace's points (module docstring)."""
    about = trace.points_m - np.asarray(trace.center_m)
    unit = about / np.hypot(*about.T)[:, None]
    total = np.zeros(trace.points_m.shape[0])
    for axis, pitch in fit.pitch_mm.items():
        k = PLANE_AXES[axis]
        phase = 2.0 * math.pi * trace.points_m[:, k] / (pitch * M_PER_MM) + fit.phase_rad[axis]
        total += unit[:, k] * fit.amplitude_um[axis] / UM_PER_M * np.sin(phase)
    return total
