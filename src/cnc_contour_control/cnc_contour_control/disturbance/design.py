"""Design of paper 002's disturbance paths: the PDC's L and W, the DOB's Q, the MBDA's PI (ROS-free).

Periodic disturbance canceller (paper 002, Eqs. 11-31)::

    L(z⁻¹)  = L_min L_max / (L_min(1) L_max(1))       linear-phase FIR, order M = 4·(number of zeros)
    L_min   = Π_k (1 − z_k z⁻¹)(1 − z_k* z⁻¹),  L_max(z⁻¹) = L_min(z) z^−M/2
    z_k     = r_k e^{jθ_k},  0 < r_k < 1
    M_L     = |L(f_d)|,  D_L = M/2 samples
    P_m     = M_L z^−D_L P_n                            (the modified model; M_L optional, see below)
    W       : N-tap FIR with W(f_d) P_m(f_d) = 1       (RLS on s(n) = sin(2π n f_d T), Eqs. 26-31)
    H       = L·W,  so that H(f_d) P_n(f_d) = 1         (gain 1, phase 0 at f_d)

With the paper's zeros as printed (angles 1.3π, 1.57π, 1.86π) L is a high-pass
(|L(50 Hz)| = 0.43, 51 at Nyquist); :func:`linear_phase_lowpass` refuses it.
The negated zeros (0.3π, 0.57π, 0.86π) give the low-pass with M_L = 0.69
(``docs/paper002_design.md``). N = 3 taps leave one degree of freedom for a
single sinusoid: ``spare_dof="zero_dc"`` spends it on W(1) = 0 (no DC action);
``"rls"`` leaves it to the RLS start, as the paper does.

Disturbance observer: the Umeno-Hori Q filter (Eq. 32) with binomial
coefficients C(K, k) (the printed K!/(K−k)! lacks the k!), so the denominator
is (1 + τs)^K, discretised with a zero-order hold. MBDA: the PI
M(s) = k_p + k_i/s by the backward difference.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from cnc_contour_control.core.config import require_range
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.velocity_models import DiscreteVelocityModel

#: Largest |L| a low-pass may reach above DC (1 plus rounding).
LOWPASS_PEAK_LIMIT = 1.0 + 1e-9
#: Frequency points for the low-pass check.
CHECK_POINTS = 1024
#: Spare-degree-of-freedom choices for W.
SPARE_DOF_CHOICES = ("rls", "zero_dc")

Polynomial = tuple[float, ...]


def disturbance_frequency_hz(spindle_rpm: float, flutes: int) -> float:
    """Eq. 2: f_d = spindle speed [rpm] × flutes / 60 [Hz]."""
    return float(spindle_rpm) * int(flutes) / 60.0


def require_below_nyquist(name: str, f_hz: float, sample_time_s: float) -> float:
    """Return ``f_hz`` if 0 < f < 1/(2T); else a :class:`ConfigError` naming ``name``, the bound and the value."""
    nyquist_hz = 0.5 / sample_time_s
    if not 0.0 < f_hz < nyquist_hz:
        raise ConfigError(f"{name} must be in (0, {nyquist_hz:g}) Hz (below Nyquist at T = {sample_time_s:g} s), "
                          f"got {f_hz:g}")
    return f_hz


def response(numerator: Sequence[float] | np.ndarray, denominator: Sequence[float] | np.ndarray,
             f_hz: np.ndarray | float, sample_time_s: float) -> np.ndarray:
    """Frequency response of b(z⁻¹)/a(z⁻¹) at ``f_hz`` [Hz] (complex, shape of ``np.atleast_1d(f_hz)``)."""
    from scipy import signal
    worn = np.atleast_1d(np.asarray(f_hz, dtype=float))
    return signal.freqz(numerator, denominator, worN=worn, fs=1.0 / sample_time_s)[1]


def linear_phase_lowpass(radii: Sequence[float], angles_rad: Sequence[float], order: int,
                         require_lowpass: bool = True) -> np.ndarray:
    """Eqs. 18-22: the unit-DC-gain linear-phase FIR L from its zeros r_k e^{jθ_k} (taps, length order + 1).

    ``require_lowpass=False`` skips the low-pass check (to measure the printed zeros' filter).

    Raises
    ------
    ConfigError
        ``order`` odd or not 4 × the number of zeros, a radius outside (0, 1),
        a DC gain of zero (a zero on z = 1), or a filter that is no low-pass
        (|L| > 1 somewhere above DC: the printed zeros of paper 002).
    """
    from scipy import signal
    if order % 2:
        raise ConfigError(f"filter_order must be even (integer delay D_L = M/2), got {order}")
    if len(radii) != len(angles_rad) or order != 4 * len(radii):
        raise ConfigError(f"filter_order {order} needs {order // 4} zeros (M/4) in zero_radii and zero_angles_pi, "
                          f"got {len(radii)} and {len(angles_rad)}")
    for k, r in enumerate(radii):
        if not 0.0 < r < 1.0:
            raise ConfigError(f"zero_radii[{k}] must be in (0, 1) (L_min minimum phase), got {r}")
    zeros = [r * np.exp(1j * a) for r, a in zip(radii, angles_rad)]
    l_min = np.real(np.poly(zeros + [np.conj(z) for z in zeros]))
    taps = np.convolve(l_min, l_min[::-1])  # L_max(z⁻¹) = L_min(z) z^−M/2: the reversed coefficients
    dc = float(np.sum(taps))
    if abs(dc) < 1e-12:
        raise ConfigError(f"zeros give L(1) = {dc:g}: no unit-DC-gain filter (a zero on z = 1)")
    taps = taps / dc
    peak = float(np.max(np.abs(signal.freqz(taps, 1, worN=CHECK_POINTS)[1])))
    if require_lowpass and peak > LOWPASS_PEAK_LIMIT:
        raise ConfigError(f"zeros give no low-pass: max |L| must be <= 1, got {peak:.3g} "
                          f"(paper 002's zeros as printed do this; negate them)")
    return taps


def rls_fit(x: np.ndarray, s: np.ndarray, taps: int, delta: float) -> np.ndarray:
    """Eqs. 28-31: W minimising Σ|s(i) − Wᵀ X(i)|², X(i) = [x(i), ..., x(i−N+1)], R(0) = I/δ, W(0) = 0."""
    r_mat = np.eye(taps) / delta
    w = np.zeros(taps)
    regressor = np.zeros(taps)
    for x_n, s_n in zip(x, s):
        regressor = np.concatenate(([x_n], regressor[:-1]))
        rx = r_mat @ regressor
        gain = rx / (1.0 + regressor @ rx)
        w = w + gain * (s_n - w @ regressor)
        r_mat = r_mat - np.outer(gain, regressor @ r_mat)
    return w


@dataclass(frozen=True)
class PdcDesign:
    """One PDC design (plain values; ``H = L·W``).

    Attributes
    ----------
    f_d_hz : float
        The disturbance frequency designed for [Hz].
    lowpass : tuple of float
        L's taps (z⁻¹ powers 0..M).
    magnitude_ml : float
        M_L = |L(f_d)|.
    delay_samples : int
        D_L = M/2.
    w : tuple of float
        W's taps.
    h : tuple of float
        H = L·W as one FIR's taps.
    hp_at_fd : complex
        H(f_d) P_n(f_d) (1 + 0j when the design holds).
    """

    f_d_hz: float
    lowpass: tuple[float, ...]
    magnitude_ml: float
    delay_samples: int
    w: tuple[float, ...]
    h: tuple[float, ...]
    hp_at_fd: complex


def _target(model: DiscreteVelocityModel, lowpass: np.ndarray, f_d_hz: float, include_ml: bool) -> complex:
    """1/P_m(f_d), P_m = [M_L] z^−D_L P_n."""
    t = model.sample_time_s
    ml = abs(complex(response(lowpass, [1.0], f_d_hz, t)[0])) if include_ml else 1.0
    delay = (len(lowpass) - 1) // 2
    pm = ml * np.exp(-2j * np.pi * f_d_hz * t * delay) * complex(response(model.numerator, model.denominator,
                                                                          f_d_hz, t)[0])
    return 1.0 / pm


def _fit_rls(model: DiscreteVelocityModel, lowpass: np.ndarray, f_d_hz: float, taps: int, include_ml: bool,
             delta: float, samples: int) -> np.ndarray:
    """W by the paper's RLS on s(n) = sin(2π n f_d T) through P_m."""
    from scipy import signal
    t = model.sample_time_s
    ml = abs(complex(response(lowpass, [1.0], f_d_hz, t)[0])) if include_ml else 1.0
    s = np.sin(2.0 * np.pi * f_d_hz * t * np.arange(samples))
    delayed = np.concatenate((np.zeros((len(lowpass) - 1) // 2), np.asarray(model.numerator) * ml))
    return rls_fit(signal.lfilter(delayed, model.denominator, s), s, taps, delta)


def _fit_zero_dc(target: complex, f_d_hz: float, taps: int, sample_time_s: float) -> np.ndarray:
    """The minimum-norm W with W(f_d) = target and W(1) = 0 (exact for 3 taps)."""
    phasors = np.exp(-2j * np.pi * f_d_hz * sample_time_s * np.arange(taps))
    rows = np.vstack((phasors.real, phasors.imag, np.ones(taps)))
    return np.linalg.lstsq(rows, np.array([target.real, target.imag, 0.0]), rcond=None)[0]


@lru_cache(maxsize=64)
def design_pdc(model: DiscreteVelocityModel, f_d_hz: float, radii: tuple[float, ...], angles_rad: tuple[float, ...],
               order: int, taps: int = 3, spare_dof: str = "zero_dc", include_ml: bool = True,
               rls_delta: float = 1e-5, rls_samples: int = 2000, tolerance: float = 0.005) -> PdcDesign:
    """Design L, P_m and W for ``f_d_hz`` and the nominal model (cached: a repeated config costs nothing).

    Raises
    ------
    ConfigError
        f_d at or above Nyquist, a bad L (:func:`linear_phase_lowpass`), an
        unknown ``spare_dof``, or a W whose W·P_m at f_d misses 1 by more than
        ``tolerance`` (the RLS did not converge).
    """
    t = model.sample_time_s
    require_below_nyquist("f_d_hz", f_d_hz, t)
    lowpass = linear_phase_lowpass(radii, angles_rad, order)
    target = _target(model, lowpass, f_d_hz, include_ml)
    if spare_dof == "zero_dc" and taps >= 3:
        w = _fit_zero_dc(target, f_d_hz, taps, t)
    elif spare_dof in SPARE_DOF_CHOICES:
        w = _fit_rls(model, lowpass, f_d_hz, taps, include_ml, rls_delta, rls_samples)
    else:
        raise ConfigError(f"spare_dof must be one of {list(SPARE_DOF_CHOICES)}, got {spare_dof!r}")
    miss = abs(complex(response(w, [1.0], f_d_hz, t)[0]) / target - 1.0)
    if not np.all(np.isfinite(w)) or miss > tolerance:
        raise ConfigError(f"RLS for W did not converge: |W·P_m(f_d) − 1| must be <= {tolerance}, got {miss:.3g} "
                          f"(f_d_hz {f_d_hz:g}, taps {taps}, rls_samples {rls_samples}, rls_delta {rls_delta:g})")
    h = np.convolve(lowpass, w)
    hp = complex(response(h, [1.0], f_d_hz, t)[0] * response(model.numerator, model.denominator, f_d_hz, t)[0])
    return PdcDesign(f_d_hz, tuple(lowpass), abs(complex(response(lowpass, [1.0], f_d_hz, t)[0])),
                     order // 2, tuple(w), tuple(h), hp)


def model_relative_degree(model: DiscreteVelocityModel) -> int:
    """Leading zero coefficients of the model's numerator in z⁻¹ (1 for Eqs. 35-36: one sample of delay)."""
    nonzero = np.flatnonzero(np.asarray(model.numerator) != 0.0)
    return int(nonzero[0]) if nonzero.size else len(model.numerator)


def q_filter_continuous(order: int, relative_degree: int, time_constant_s: float) -> tuple[Polynomial, Polynomial]:
    """Eq. 32 with binomial coefficients C(K, k) (powers of s, highest first).

    Numerator Σ_{k≤K−r} C(K, k)(τs)^k, denominator (1 + τs)^K.
    """
    from scipy.special import comb
    num = [comb(order, k, exact=True) * time_constant_s ** k for k in range(order - relative_degree + 1)]
    den = [comb(order, k, exact=True) * time_constant_s ** k for k in range(order + 1)]
    return tuple(float(v) for v in num[::-1]), tuple(float(v) for v in den[::-1])


def q_filter(order: int, relative_degree: int, time_constant_s: float,
             model: DiscreteVelocityModel) -> tuple[Polynomial, Polynomial]:
    """The Q filter in z⁻¹ (zero-order hold at the model's sample time), strictly proper like the model.

    Raises
    ------
    ConfigError
        ``relative_degree`` below the model's (Q·P_n⁻¹ would be improper) or above ``order``.
    """
    from scipy import signal
    needed = model_relative_degree(model)
    if relative_degree < needed:
        raise ConfigError(f"q_relative_degree must be >= {needed} (the model's relative degree), got {relative_degree}")
    if relative_degree > order:
        raise ConfigError(f"q_relative_degree must be <= q_order {order}, got {relative_degree}")
    require_range("q_time_constant_s", time_constant_s, model.sample_time_s / 100.0, 10.0)
    num, den = q_filter_continuous(order, relative_degree, time_constant_s)
    b, a, _ = signal.cont2discrete((num, den), model.sample_time_s, method="zoh")
    b = np.ravel(b)
    b[np.abs(b) < 1e-14 * np.max(np.abs(b))] = 0.0  # the ZOH's exact leading zero, as computed
    return tuple(float(v) for v in b), tuple(float(v) for v in np.ravel(a))


def mbda_pi(kp: float, ki_per_s: float, sample_time_s: float) -> tuple[Polynomial, Polynomial]:
    """M(z⁻¹) = k_p + k_i T/(1 − z⁻¹) (backward difference of k_p + k_i/s)."""
    from scipy import signal
    b, a, _ = signal.cont2discrete(([kp, ki_per_s], [1.0, 0.0]), sample_time_s, method="backward_diff")
    return tuple(float(v) for v in np.ravel(b)), tuple(float(v) for v in np.ravel(a))


def strip_delay(numerator: Sequence[float], samples: int) -> Polynomial:
    """b(z⁻¹)/z⁻ⁿ: drop ``samples`` leading coefficients that must be zero."""
    head = [float(v) for v in numerator[:samples]]
    if any(head):
        raise ConfigError(f"numerator must start with {samples} zero coefficients, got {head}")
    return tuple(float(v) for v in numerator[samples:]) or (0.0,)


def dob_filters(q: tuple[Polynomial, Polynomial],
                model: DiscreteVelocityModel) -> tuple[tuple[Polynomial, Polynomial], tuple[Polynomial, Polynomial]]:
    """The DOB's two filters: (Q·P_n⁻¹ on the velocity, Q/z⁻¹ on the previous command).

    d̂(k) = [Q P_n⁻¹] y(k) − [Q/z⁻¹] u(k−1); both proper because Q's relative
    degree is at least the model's.
    """
    delay = model_relative_degree(model)
    q_num = strip_delay(q[0], delay)
    p_num = strip_delay(model.numerator, delay)
    inverse = (tuple(np.polymul(q_num, model.denominator)), tuple(np.polymul(q[1], p_num)))
    return inverse, (q_num, q[1])


def bode_phase_deg(value: complex) -> float:
    """Phase of a complex response in degrees, in (−180, 180]."""
    return math.degrees(math.atan2(value.imag, value.real))
