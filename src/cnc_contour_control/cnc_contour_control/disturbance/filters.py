"""Per-sample linear filters for the disturbance laws (ROS-free, hand-written for speed).

Two forms, both checked against :func:`scipy.signal.lfilter` in ``test_dob_filters``:

* :class:`IirFilter`: ``a_0 y(k) = Σ b_i x(k−i) − Σ_{i≥1} a_i y(k−i)`` in the
  transposed direct form II (the state of ``lfilter``'s ``zi``);
* :class:`FirFilter`: ``y(k) = Σ h_i x(k−i)`` over a delay line of past
  inputs, so new taps (a redesign) take effect without a bump: the history
  is the signal's, not the coefficients'.

Coefficients are polynomials in z⁻¹, as :func:`scipy.signal.lfilter` takes them.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from operator import mul

from cnc_contour_control.core.errors import ConfigError


class IirFilter:
    """``b(z⁻¹)/a(z⁻¹)`` stepped one sample at a time (transposed direct form II).

    Parameters
    ----------
    numerator : sequence of float
        b_0, b_1, ... (any length).
    denominator : sequence of float
        a_0, a_1, ... with a_0 ≠ 0 (normalised to 1 here).
    """

    def __init__(self, numerator: Sequence[float], denominator: Sequence[float]) -> None:
        if len(denominator) == 0 or float(denominator[0]) == 0.0:
            raise ConfigError(f"denominator[0] must be nonzero, got {list(denominator)!r}")
        a0 = float(denominator[0])
        n = max(len(numerator), len(denominator))
        self._b = [float(v) / a0 for v in numerator] + [0.0] * (n - len(numerator))
        self._a = [float(v) / a0 for v in denominator] + [0.0] * (n - len(denominator))
        self._z = [0.0] * (n - 1)

    def reset(self) -> None:
        """Zero the state (as at start-up)."""
        self._z = [0.0] * len(self._z)

    def step(self, x: float) -> float:
        """One input sample -> one output sample."""
        b, a, z = self._b, self._a, self._z
        y = b[0] * x + (z[0] if z else 0.0)
        last = len(z) - 1
        for i in range(last):
            z[i] = b[i + 1] * x - a[i + 1] * y + z[i + 1]
        if last >= 0:
            z[last] = b[last + 1] * x - a[last + 1] * y
        return y


class FirFilter:
    """``Σ h_i x(k−i)`` over a delay line of the last ``len(h)`` inputs.

    Parameters
    ----------
    taps : sequence of float
        h_0, h_1, ... (at least one).
    """

    def __init__(self, taps: Sequence[float]) -> None:
        if len(taps) == 0:
            raise ConfigError("taps must have at least one coefficient, got none")
        self._h = [float(v) for v in taps]
        self._x: deque[float] = deque([0.0] * len(self._h), maxlen=len(self._h))

    def reset(self) -> None:
        """Zero the input history."""
        self._x.extend([0.0] * len(self._h))

    def set_taps(self, taps: Sequence[float]) -> None:
        """New taps keeping the input history (a longer filter starts with zeros beyond it)."""
        history = list(self._x) + [0.0] * max(0, len(taps) - len(self._x))
        self._h = [float(v) for v in taps]
        self._x = deque(history[:len(self._h)], maxlen=len(self._h))

    def step(self, x: float) -> float:
        """One input sample -> one output sample."""
        self._x.appendleft(x)
        return sum(map(mul, self._h, self._x))
