"""What the paper-002 bench measures in a run: the contour error at constant speed, its RMS and its f_d line.

- :func:`signed_contour_error`: the scorer's exact contour error
  (:meth:`Program.contour_distance`) with the sign of the nearest segment's
  ``signed_error`` (left of a line / outside the circle > 0), so a periodic
  error stays a sinusoid (the unsigned distance would rectify it).
- :func:`constant_speed_mask`: the samples where the reference moves at the
  programmed feed (within ``tolerance``): the paper's "constant speed".
- :func:`lock_in_amplitude`: the amplitude of one frequency in a sampled
  signal, after a polynomial detrend (the slow lag of the P loop) and under a
  Hann window (leakage of the slow part and of the friction glitches falls off
  fast), so it needs no whole number of periods. Encoder quantisation is
  broadband: it sets an RMS floor that hides removal in plain RMS, but adds
  little at one frequency, which is why the bench reports both.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from cnc_contour_control.errors import ConfigError
from cnc_contour_control.geometry import Program
from cnc_tools.run_record import RunRecord

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Degree of the polynomial taken out before the lock-in.
DETREND_DEGREE = 3
#: Relative deviation of the reference speed from the programmed feed that still counts as constant speed.
SPEED_TOLERANCE = 1.0e-3


def signed_contour_error(program: Program, points_m: FloatArray) -> FloatArray:
    """Contour error [m], shape (N,): the exact distance to ``program`` signed by the nearest segment's side."""
    distance, index = program.contour_distance(points_m)
    sign = np.ones_like(distance)
    for i, segment in enumerate(program.segments):
        mine = index == i
        if np.any(mine):
            sign[mine] = np.where(segment.signed_error(points_m[mine]) < 0.0, -1.0, 1.0)
    return sign * distance


def constant_speed_mask(record: RunRecord, tolerance: float = SPEED_TOLERANCE) -> BoolArray:
    """Samples (N,) whose reference speed is the programmed feed to ``tolerance`` (relative)."""
    reference = record.reference
    if reference is None:
        raise ConfigError(f"run {record.name}: the constant-speed window needs the reference series")
    programmed = np.array([segment.feed_m_s for segment in record.program.segments])[reference.segment_index]
    return ~reference.done & (np.abs(reference.feed_m_s - programmed) <= tolerance * programmed)


def lock_in_amplitude(t_s: FloatArray, x: FloatArray, f_hz: float, degree: int = DETREND_DEGREE) -> float:
    """Amplitude of the ``f_hz`` component of ``x`` (same unit as ``x``), detrended, Hann-windowed.

    Raises
    ------
    ConfigError
        If fewer than two periods of ``f_hz`` are in the window.
    """
    t = np.asarray(t_s, dtype=float)
    if t.size < 2 or (t[-1] - t[0]) * f_hz < 2.0:
        span = float(t[-1] - t[0]) if t.size else 0.0
        raise ConfigError(f"lock-in needs >= 2 periods of f_hz {f_hz:g} in its window, got {span:g} s")
    centred = t - t.mean()
    scale = max(float(np.max(np.abs(centred))), 1e-12)
    residual = x - np.polyval(np.polyfit(centred / scale, x, degree), centred / scale)
    window = np.hanning(t.size)
    return float(2.0 * abs(np.sum(window * residual * np.exp(-2j * np.pi * f_hz * t))) / np.sum(window))


def rms(x: FloatArray) -> float:
    """Root mean square (nan for no samples)."""
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else float("nan")
