"""What the paper-002 bench measures in a run: the contour error at constant speed, its RMS and its f_d line.

- The contour error is :func:`cnc_contour_control.estimators.signed_contour_error`:
  the scorer's exact distance (:meth:`Program.contour_distance`) with a side
  (left of travel > 0), so a periodic error stays a sinusoid (the unsigned
  distance would rectify it).
- :func:`constant_speed_mask`: the samples where the reference moves at the
  programmed feed (within ``tolerance``): the paper's "constant speed".
- :func:`lock_in_amplitude`: the amplitude of one frequency in a sampled
  signal, after a polynomial detrend (the slow lag of the P loop) and under a
  Hann window (leakage of the slow part and of the friction glitches falls off
  fast), so it needs no whole number of periods. Encoder quantisation is
  broadband: it sets an RMS floor that hides removal in plain RMS, but adds
  little at one frequency, which is why the bench reports both.
- :func:`sliding_lock_in` and :func:`recovery_time_s`: the lock-in over a
  window sliding through a run, and how long after a spindle step the f_d
  line stays under a share of the P loop's (the step's recovery time).
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.run_record import RunRecord

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Degree of the polynomial taken out before the lock-in.
DETREND_DEGREE = 3
#: Relative deviation of the reference speed from the programmed feed that still counts as constant speed.
SPEED_TOLERANCE = 1.0e-3


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


def sliding_lock_in(t_s: FloatArray, x: FloatArray, f_hz: float, window_s: float,
                    hop_s: float) -> tuple[FloatArray, FloatArray]:
    """:func:`lock_in_amplitude` of ``x`` at ``f_hz`` over windows of ``window_s`` every ``hop_s``.

    Returns the window ends [s] and the amplitudes (unit of ``x``), each shape (W,).
    """
    t = np.asarray(t_s, dtype=float)
    ends = np.arange(t[0] + window_s, t[-1] + 0.5 * hop_s, hop_s)
    amplitudes = np.empty(ends.size)
    for i, end in enumerate(ends):
        inside = (t > end - window_s) & (t <= end)
        amplitudes[i] = lock_in_amplitude(t[inside], x[inside], f_hz)
    return ends, amplitudes


def recovery_time_s(ends_s: FloatArray, law: FloatArray, bare: FloatArray, goal: float, step_s: float,
                    window_s: float) -> float:
    """Time from ``step_s`` to the end of the first window after which every window removes >= ``goal``.

    Only windows wholly after the step count (so the answer is >= ``window_s``, the resolution). ``law``
    and ``bare`` are the sliding f_d lines (same windows) of the law and of the P loop; removal is
    ``1 − law/bare``. nan when the last window still misses the goal.
    """
    after = ends_s >= step_s + window_s - 1e-9
    met = (1.0 - law / bare >= goal) & after
    missing = np.flatnonzero(after & ~met)
    if missing.size and missing[-1] == ends_s.size - 1:
        return float("nan")
    first = missing[-1] + 1 if missing.size else int(np.flatnonzero(after)[0])
    return float(ends_s[first] - step_s)


def rms(x: FloatArray) -> float:
    """Root mean square (nan for no samples)."""
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else float("nan")
