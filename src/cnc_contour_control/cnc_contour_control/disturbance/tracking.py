"""On-line estimate of the periodic disturbance's frequency f_d from the PDC's residual (ROS-free).

The PDC's residual ρ(k) = y(k) − [P_n v](k) is P_n d(k) when the model holds,
whatever the paths cancel (v already carries −T_E), so f_d can be read from it
while the canceller works. A heterodyne frequency-locked estimate::

    z(k)  = ρ(k) e^{−j2π f_0 k T}                 shift f_0 (the commanded spindle's f_d) to 0 Hz
    b(k)  = B(z⁻¹) z(k)                           B: Butterworth low-pass, order 2, corner ``band`` · f_0:
                                                  keeps |f − f_0| < corner; the slow part of ρ (friction,
                                                  at −f_0 after the shift) and the image (at −2 f_0) fall away
    a(k)  = λ a(k−1) + (1 − λ) b(k) b*(k−1)       amplitude-weighted phase increment, λ = e^{−T/τ}
    f̂(k) = f_0 + arg a(k) / (2π T)               clamped to f_0 (1 ± band)

A stationary sinusoid at f gives b(k) b*(k−1) = |b|² e^{j2π (f − f_0) T}
exactly, whatever B's gain and phase at f − f_0, so f̂ has no bias from the
filter; noise and the image only add ripple, which λ averages. The estimate
counts from ``settle_s`` on and only while the line's amplitude, 2 (mean |b|²)^½,
exceeds ``min_amplitude`` (a run without the disturbance never redesigns).

``B`` steps through :class:`~cnc_contour_control.disturbance.filters.IirFilter`
(real and imaginary parts), the filter tested against :func:`scipy.signal.lfilter`.
"""
from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

from cnc_contour_control.core.config import require_range
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.disturbance.filters import IirFilter

#: Order of the Butterworth low-pass B.
LOWPASS_ORDER = 2


@dataclass(frozen=True)
class TrackerConfig:
    """A frequency tracker around ``center_hz``.

    Parameters
    ----------
    center_hz : float
        f_0 [Hz], the frequency the spindle is commanded to give; in (0, Nyquist).
    sample_time_s : float
        T [s], > 0.
    band : float
        Half-width of the search band as a fraction of f_0, in [0.01, 0.5]; also B's corner (band · f_0).
    averaging_s : float
        τ of the phase-increment average [s], in [T, 10].
    settle_s : float
        No estimate before this time from the start [s], in [0, 10].
    min_amplitude : float
        Smallest amplitude of the line near f_0 that gives an estimate [unit of ρ], >= 0.
    """

    center_hz: float
    sample_time_s: float
    band: float = 0.1
    averaging_s: float = 0.05
    settle_s: float = 0.15
    min_amplitude: float = 0.0

    def __post_init__(self) -> None:
        require_range("sample_time_s", self.sample_time_s, 1e-6, 1.0)
        nyquist_hz = 0.5 / self.sample_time_s
        require_range("band", self.band, 0.01, 0.5)
        if not 0.0 < self.center_hz * (1.0 + self.band) < nyquist_hz:
            raise ConfigError(f"center_hz · (1 + band) must be in (0, {nyquist_hz:g}) Hz (Nyquist at T = "
                              f"{self.sample_time_s:g} s), got {self.center_hz * (1.0 + self.band):g}")
        require_range("averaging_s", self.averaging_s, self.sample_time_s, 10.0)
        require_range("settle_s", self.settle_s, 0.0, 10.0)
        require_range("min_amplitude", self.min_amplitude, 0.0, math.inf)

    def lowpass(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """B(z⁻¹): Butterworth, order :data:`LOWPASS_ORDER`, corner band · f_0 (``scipy.signal.butter``)."""
        from scipy import signal
        b, a = signal.butter(LOWPASS_ORDER, self.band * self.center_hz, fs=1.0 / self.sample_time_s)
        return tuple(float(v) for v in b), tuple(float(v) for v in a)


class FrequencyTracker:
    """The heterodyne estimate of the module docstring, one sample at a time.

    Attributes
    ----------
    estimate_hz : float or None
        f̂ [Hz] after the last step (None while settling or below ``min_amplitude``).
    """

    def __init__(self, config: TrackerConfig) -> None:
        self.config = config
        b, a = config.lowpass()
        self._real, self._imag = IirFilter(b, a), IirFilter(b, a)
        self._cycles_per_sample = config.center_hz * config.sample_time_s
        self._keep = math.exp(-config.sample_time_s / config.averaging_s)
        self._settle = round(config.settle_s / config.sample_time_s)
        self._low, self._high = (config.center_hz * (1.0 - config.band), config.center_hz * (1.0 + config.band))
        self.reset()

    def reset(self) -> None:
        """Back to the start (filters, average and sample count zero)."""
        self._real.reset()
        self._imag.reset()
        self._k = 0
        self._previous = 0j
        self._increment = 0j
        self._power = 0.0
        self.estimate_hz: float | None = None

    def shifted(self, residual: float) -> complex:
        """One sample of b(k) = B[ρ e^{−j2π f_0 k T}] (advances the sample count)."""
        phase = (self._k * self._cycles_per_sample) % 1.0
        z = residual * cmath.exp(-2j * math.pi * phase)
        self._k += 1
        return complex(self._real.step(z.real), self._imag.step(z.imag))

    def step(self, residual: float) -> float | None:
        """One residual sample [unit of ρ] -> f̂ [Hz], or None (settling, or no line above ``min_amplitude``)."""
        b = self.shifted(residual)
        keep = self._keep
        self._increment = keep * self._increment + (1.0 - keep) * b * self._previous.conjugate()
        self._power = keep * self._power + (1.0 - keep) * (b.real * b.real + b.imag * b.imag)
        self._previous = b
        if self._k <= self._settle or 4.0 * self._power <= self.config.min_amplitude ** 2:
            self.estimate_hz = None
            return None
        offset = math.atan2(self._increment.imag, self._increment.real) / (2.0 * math.pi * self.config.sample_time_s)
        self.estimate_hz = min(max(self.config.center_hz + offset, self._low), self._high)
        return self.estimate_hz


#: Redesign grid of a tracking PDC, as a fraction of the commanded f_d (0.25 Hz at 50 Hz).
RESOLUTION = 0.005
#: The estimate must leave the design by this many grid steps before the PDC redesigns (no chatter).
HYSTERESIS_STEPS = 0.75


def tracked_rpm(commanded_rpm: float, center_hz: float, estimate_hz: float, design_rpm: float,
                resolution: float = RESOLUTION) -> float | None:
    """The spindle speed [rpm] a tracking PDC redesigns for, or None to keep its design.

    The estimate f̂ [Hz] maps to the grid ``commanded_rpm · (1 + resolution · n)`` nearest
    ``commanded_rpm · f̂ / center_hz``; None while f̂ stays within ``HYSTERESIS_STEPS`` grid steps of
    the design's speed ``design_rpm`` or rounds to it.
    """
    ratio, design_ratio = estimate_hz / center_hz, design_rpm / commanded_rpm
    if abs(ratio - design_ratio) <= HYSTERESIS_STEPS * resolution:
        return None
    rpm = commanded_rpm * (1.0 + resolution * round((ratio - 1.0) / resolution))
    return None if rpm == design_rpm else rpm
