"""Run-to-run iterative learning control (ILC) in contour space, with a zero-phase Q filter.

Run k plays a stored feedforward a_k(t) [drive units] along the normal of the
contour and records the contour error e_k(t) = ε_c(t) [m]; after the run::

    a_{k+1}(t) = Q( a_k(t) + L · e_k(t + d) )                    L [drive units/m], d samples
    corr_i(t)  = −n_i(θ_t) · a_k(t) · g_i,   n = (−sin θ, cos θ)  axes 1 and 2; 0 on the others

so a positive ε_c (to the left of travel) is pushed to the right next run.
The time advance d (``advance_samples``) accounts for the lag from a
correction to the contour error it moves; Q is a Butterworth low-pass of
order ``filter_order`` and cut-off ``cutoff_hz`` run forward and backward
(``scipy.signal.filtfilt``: no phase shift, the square of its gain), which
keeps the learning from amplifying what the loop cannot follow. θ_t is the
current run's direction of travel (the same path gives the same θ(t)).

**Run length.** The ticks of a run are expected to count 0, 1, 2, ... A run
longer than the stored a_k gets 0 past its end; at :meth:`end_run` a_k is cut
or padded with zeros to this run's length M, and e_k(t + d) is 0 where
t + d ≥ M, so a_{k+1} has M samples.

**Guard.** A non-finite a_{k+1} keeps a_k, stops learning and sets
:attr:`fault`; each correction is clipped to ±``output_limit``.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cnc_contour_control.compensators.base import MAX_GAIN, AxisCorrection, CompensatorSample, check_sample, factors_for
from cnc_contour_control.compensators.state_file import FloatArray, load_state, save_state
from cnc_contour_control.core.config import require_positive
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import param

_WHO = "ilc compensator"


@dataclass(frozen=True)
class IlcConfig(AxisCorrection):
    """Configuration of the contour-space ILC.

    Parameters
    ----------
    learning_gain : float
        L [drive units per m of contour error], in [0, 1e12].
    advance_samples : int
        Time advance d of the error in the update [samples], in [0, 10000].
    cutoff_hz : float
        Cut-off of the zero-phase Butterworth Q [Hz], in [1e-3, 1e6]; below the Nyquist frequency.
    filter_order : int
        Order of the Butterworth Q (doubled by filtfilt), in [1, 8].
    axis_gains, output_limit
        As :class:`~cnc_contour_control.compensators.base.AxisCorrection`.
    """

    learning_gain: float = param(1.0e5, unit="drive/m", low=0.0, high=MAX_GAIN,
                                 description="learning gain L on the contour error")
    advance_samples: int = param(5, unit="samples", low=0, high=10000, description="time advance d of the error")
    cutoff_hz: float = param(20.0, unit="Hz", low=1.0e-3, high=1.0e6, description="cut-off of the zero-phase Q filter")
    filter_order: int = param(2, low=1, high=8, description="order of the Butterworth Q filter")

    def __post_init__(self) -> None:
        for name in ("advance_samples", "filter_order"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ConfigError(f"ilc.{name} must be an integer, got {value!r}")
        self.check("ilc")


class IterativeLearningCompensator:
    """Contour-space ILC (see the module docstring).

    Parameters
    ----------
    config : IlcConfig
        Validated configuration.
    axis_names : sequence of str
        The axes; the first two span the contour plane.
    sample_time_s : float
        The run's sample period [s] (designs Q; a stored a_k is for this period only).
    """

    def __init__(self, config: IlcConfig, axis_names: Sequence[str], sample_time_s: float) -> None:
        from scipy import signal
        self.config = config
        self.axis_names = tuple(axis_names)
        self.sample_time_s = require_positive("sample_time_s", sample_time_s, "ilc")
        nyquist_hz = 0.5 / self.sample_time_s
        if not config.cutoff_hz < nyquist_hz:
            raise ConfigError(f"ilc.cutoff_hz must be < the Nyquist frequency {nyquist_hz:g} Hz at "
                              f"sample_time_s {self.sample_time_s:g}, got {config.cutoff_hz!r}")
        self._b, self._a = signal.butter(config.filter_order, config.cutoff_hz, fs=1.0 / self.sample_time_s)
        self._gains = factors_for("axis_gains", config.axis_gains, self.axis_names, "ilc")
        self.frozen = False
        self.fault: str | None = None
        self._feedforward: list[float] = []
        self._zeros = [0.0] * len(self.axis_names)
        self.reset()

    @property
    def feedforward(self) -> FloatArray:
        """The stored a_k [drive units], one value per tick (a copy)."""
        return np.array(self._feedforward)

    def reset(self) -> None:
        """Start of a run: forget the recorded errors, keep a_k."""
        self._errors: list[float] = []

    def step(self, sample: CompensatorSample) -> list[float]:
        """Record ε_c, return a_k(tick) along −n on the axes [drive units] (a fresh list)."""
        check_sample(_WHO, sample, self.axis_names)
        self._errors.append(sample.contour_error_m)
        out = self._zeros[:]
        tick, stored = sample.tick, self._feedforward
        if self.fault is not None or tick >= len(stored):
            return out
        push, clip = stored[tick], self.config.output_limit
        normal = (-math.sin(sample.angle_rad), math.cos(sample.angle_rad))
        for k in range(min(2, len(out))):
            value = -normal[k] * push * self._gains[k]
            out[k] = -clip if value < -clip else (clip if value > clip else value)
        return out

    def end_run(self) -> None:
        """a_{k+1} = Q(a_k + L e_k(t + d)) over this run's length (unless frozen or faulted)."""
        if self.frozen or self.fault is not None or not self._errors:
            return
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is the guard's case below
            updated = self.update(np.array(self._feedforward), np.array(self._errors))
        if not np.all(np.isfinite(updated)):
            self.fault = f"{_WHO}: the learned feedforward became non-finite; learning stopped"
            return
        self._feedforward = updated.tolist()

    def update(self, feedforward: FloatArray, errors_m: FloatArray) -> FloatArray:
        """The law of one run: Q(a_k + L e_k(t + d)) with a_k cut or zero-padded to ``len(errors_m)``.

        Parameters
        ----------
        feedforward : ndarray, shape (N,)
            a_k [drive units].
        errors_m : ndarray, shape (M,)
            e_k, the run's contour errors [m].

        Returns
        -------
        ndarray, shape (M,)
            a_{k+1} [drive units].
        """
        from scipy import signal
        length, advance = len(errors_m), self.config.advance_samples
        previous = np.zeros(length)
        previous[:min(length, len(feedforward))] = feedforward[:length]
        advanced = np.zeros(length)
        if advance < length:
            advanced[:length - advance] = errors_m[advance:]
        raw = previous + self.config.learning_gain * advanced
        padlen = min(3 * max(len(self._a), len(self._b)), length - 1)
        return signal.filtfilt(self._b, self._a, raw, padlen=padlen)

    def save(self, path: str | Path) -> None:
        """Write a_k and the sample period to the ``.npz`` file ``path``."""
        save_state(path, {"feedforward": self._feedforward, "sample_time_s": self.sample_time_s})

    def load(self, path: str | Path) -> None:
        """Read a_k from ``path``; it must have been learned at this sample period. Clears the fault."""
        arrays = load_state(path, {"feedforward": (None,), "sample_time_s": ()}, f"{_WHO} feedforward")
        stored_s = float(arrays["sample_time_s"])
        if not math.isclose(stored_s, self.sample_time_s, rel_tol=1e-9):
            raise ConfigError(f"{_WHO} feedforward {str(path)!r} was learned at sample_time_s {stored_s:g}, "
                              f"this compensator runs at {self.sample_time_s:g}")
        self._feedforward = arrays["feedforward"].tolist()
        self.fault = None
        self.reset()

