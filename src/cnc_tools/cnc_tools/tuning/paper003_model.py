"""Paper 003's analytic model of a feed drive in a circular test (Eqs. 1, 8, 12-17), with its open readings.

Velocity loop (Eq. 1): ``H(s) = (c K2 s + c K1) / (s² + c K2 s + c K1)``, ``c = K_t/J_m``
(≈ 157), so ``ω_n = √(c K1)``, ``ζ = c K2 / (2 ω_n)``. The position loop (gain
``k`` [1/s]) closes around it: ``L(s) = k H(s) / s``, here with a one-sample delay.
Radius errors of a circle of radius ``R`` at feed ``F`` (all in m, m/s):

- gain mismatch (Eq. 8): ``ΔR = (F sin 2θ / 2)(1/k_x − 1/k_y)``, peak ``F |1/k_x − 1/k_y| / 2``;
- servo lag (Eq. 12): a first-order lag ``T(K1, K2)``; the paper does not say which ``T``;
- acceleration/deceleration after interpolation (Eq. 13): ``T_ip² F² / (2R)`` (exponential)
  or ``T_ip² F² / (24R)`` (linear).

Eq. 17's objective is their sum, here over the paper's grid (feeds 1000/4000/8000
mm/min × radii 1.5/3/5/10 mm × CW/CCW). What the paper leaves open is a named
option of :class:`Readings` (a registry each): which lag ``T`` (:data:`LAG_READINGS`),
how Eq. 12 becomes a radius error (:data:`LAG_FORMS`), the interpolation kind
(:data:`INTERPOLATIONS`) and how the grid is aggregated (:data:`AGGREGATES`).

Note on the lag: ``1 − H(s) = s² / (s² + 2ζω_n s + ω_n²)`` has a double zero at
``s = 0``, so a PI velocity loop follows a constant velocity *and* its integral
(position) with no steady error; only the position loop's ``1/k`` remains. The
``"pi_exact"`` lag reading is that fact (``T = 0``).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import control
import numpy as np

from cnc_contour_control.core.config import require_choice, require_non_negative, require_positive
from cnc_contour_control.core.velocity_models import PAPER003_TORQUE_PER_INERTIA

#: The paper's circular-test grid: feeds [mm/min], radii [mm], directions.
GRID_FEEDS_MM_MIN: tuple[float, ...] = (1000.0, 4000.0, 8000.0)
GRID_RADII_MM: tuple[float, ...] = (1.5, 3.0, 5.0, 10.0)
GRID_DIRECTIONS: tuple[str, ...] = ("cw", "ccw")
#: Feed of the paper's rise-time test (Fig. 4) [mm/min].
RISE_FEED_MM_MIN = 1000.0
UM_PER_M = 1.0e6
#: Points of the step response a rise time is measured on.
RISE_TIME_SAMPLES = 1500
#: Frequencies a resonance peak is searched on.
RESONANCE_POINTS = 2000
#: How ``control.stability_margins`` computes the margins.
MARGIN_METHOD = "poly"


@dataclass(frozen=True)
class PaperColumn:
    """One column of the paper's Table 2 and the results it reports for it."""

    zeta: float
    omega_n_rad_s: float
    k1: float
    k2: float
    rise_time_s: float
    radius_error_um: float


#: Table 2 and Sect. 5 of the paper: the standard and the optimal column.
PAPER003_TABLE: dict[str, PaperColumn] = {
    "standard": PaperColumn(0.71, 126.0, 101.121, 1.1396, 0.16, 135.0),
    "optimal": PaperColumn(1.63, 125.0, 99.522, 2.596, 0.13, 90.0),
}


@dataclass(frozen=True)
class Paper003Model:
    """The drive of paper 003 as its equations see it.

    Attributes
    ----------
    k1 : float
        Integral gain of the PI velocity loop K1 [Nm/rad, the paper's unit].
    k2 : float
        Proportional gain K2 [Nm·s/rad].
    torque_per_inertia : float
        K_t / J_m (≈ 157 from either column of Table 2).
    position_gain_x_1_s, position_gain_y_1_s : float
        Position-loop gains k_x, k_y [1/s] (not given by the paper).
    t_ip_s : float
        Acceleration/deceleration time constant after interpolation T_ip [s] (not given).
    sample_time_s : float
        Sample period of the position loop (its one-sample delay) [s].
    """

    k1: float = PAPER003_TABLE["standard"].k1
    k2: float = PAPER003_TABLE["standard"].k2
    torque_per_inertia: float = PAPER003_TORQUE_PER_INERTIA
    position_gain_x_1_s: float = 30.0
    position_gain_y_1_s: float = 30.0
    t_ip_s: float = 0.0
    sample_time_s: float = 0.001

    def __post_init__(self) -> None:
        for name in ("k1", "torque_per_inertia", "position_gain_x_1_s", "position_gain_y_1_s", "sample_time_s"):
            require_positive(name, getattr(self, name), "paper003 model")
        for name in ("k2", "t_ip_s"):
            require_non_negative(name, getattr(self, name), "paper003 model")

    @property
    def omega_n_rad_s(self) -> float:
        """ω_n = √(K1 K_t/J_m) [rad/s]."""
        return math.sqrt(self.k1 * self.torque_per_inertia)

    @property
    def zeta(self) -> float:
        """ζ = K2 K_t / (2 ω_n J_m)."""
        return self.k2 * self.torque_per_inertia / (2.0 * self.omega_n_rad_s)

    @property
    def position_gain_1_s(self) -> float:
        """The mean of k_x and k_y [1/s] (the loop the margins and the rise time use)."""
        return 0.5 * (self.position_gain_x_1_s + self.position_gain_y_1_s)

    def with_(self, **changes: float) -> Paper003Model:
        """A validated copy with ``changes``."""
        return replace(self, **changes)


def velocity_loop(model: Paper003Model) -> control.TransferFunction:
    """Eq. 1, velocity command -> velocity, as a python-control transfer function."""
    c = model.torque_per_inertia
    return control.tf([c * model.k2, c * model.k1], [1.0, c * model.k2, c * model.k1])


def position_open_loop(model: Paper003Model) -> control.TransferFunction:
    """``k H(s)/s`` sampled (ZOH) at the model's period, times ``z⁻¹`` (the one-sample delay)."""
    continuous = model.position_gain_1_s * velocity_loop(model) * control.tf([1.0], [1.0, 0.0])
    discrete = control.c2d(continuous, model.sample_time_s, method="zoh")
    return discrete * control.tf([1.0], [1.0, 0.0], model.sample_time_s)


def margins(model: Paper003Model) -> tuple[float, float]:
    """(phase margin [deg], gain margin [dB]) of the delayed position loop (``control.stability_margins``).

    Computed from the loop's polynomials (``method="poly"``, ten times faster than
    the frequency-response method; a test checks the two agree on this loop).
    A margin the loop does not have (no crossover) is reported as +inf.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        gm, pm, *_ = control.stability_margins(position_open_loop(model), method=MARGIN_METHOD)
    gm_db = 20.0 * math.log10(gm) if np.isfinite(gm) and gm > 0 else math.inf
    return (float(pm) if np.isfinite(pm) else math.inf), gm_db


def resonance_peak_db(system: control.TransferFunction) -> float:
    """The peak of ``|system(jω)|`` in dB (0 dB when the response never rises above its DC gain of 1).

    Evaluated on :data:`RESONANCE_POINTS` log-spaced frequencies up to Nyquist
    (discrete) or 10⁵ rad/s (continuous).
    """
    top = math.pi / system.dt if system.dt else 1.0e5
    omega = np.logspace(-1.0, math.log10(top) - 1e-9, RESONANCE_POINTS)
    with np.errstate(divide="ignore", invalid="ignore"):
        magnitude = np.abs(control.frequency_response(system, omega).magnitude).ravel()
    return float(20.0 * math.log10(max(1.0, float(np.nanmax(magnitude)))))


def closed_resonance_peak_db(model: Paper003Model) -> float:
    """Resonance peak of the closed, delayed position loop ``L / (1 + L)`` [dB]."""
    return resonance_peak_db(control.feedback(position_open_loop(model), 1))


def phase_margin_eq15_deg(zeta: float) -> float:
    """Eq. 15 / 17: ``atan(2ζ / √(√(1 + 4ζ⁴) − 2ζ²))`` in degrees.

    The phase margin of the standard second-order loop ``ω_n² / (s (s + 2ζω_n))``.
    """
    return math.degrees(math.atan2(2.0 * zeta, math.sqrt(math.sqrt(1.0 + 4.0 * zeta ** 4) - 2.0 * zeta ** 2)))


def _rise_time(system: control.TransferFunction) -> float:
    """10-90 % rise time of ``system``'s step response [s] (``control.step_info`` on a fine time grid)."""
    with np.errstate(divide="ignore", invalid="ignore"):  # the DC gain of a loop with an integrator: 0/0 handled
        response = control.step_response(system, T_num=RISE_TIME_SAMPLES)
    return float(control.step_info(response.outputs, response.time, RiseTimeLimits=(0.1, 0.9))["RiseTime"])


def rise_time_velocity_loop_s(model: Paper003Model) -> float:
    """10-90 % rise time of the velocity to a velocity step through Eq. 1 alone [s]."""
    return _rise_time(velocity_loop(model))


def rise_time_position_loop_s(model: Paper003Model) -> float:
    """10-90 % rise time of the axis velocity to a feed step through the closed position loop [s].

    A feed step is a position ramp; the velocity answers it as the position
    answers a step: ``k H / (s + k H)`` (continuous, no delay).
    """
    loop = model.position_gain_1_s * velocity_loop(model) * control.tf([1.0], [1.0, 0.0])
    return _rise_time(control.feedback(loop, 1))


# --- the readings the paper leaves open -----------------------------------------------------------------------


def _slowest_pole_time_s(model: Paper003Model) -> float:
    """1 / (the slowest pole of Eq. 1's denominator) [s]."""
    z, w = model.zeta, model.omega_n_rad_s
    rate = z * w if z <= 1.0 else w * (z - math.sqrt(z * z - 1.0))
    return 1.0 / rate


#: Which first-order lag T(K1, K2) Eqs. 9-12 mean: name -> T [s].
LAG_READINGS: dict[str, Callable[[Paper003Model], float]] = {
    "pi_exact": lambda m: 0.0,                              # the PI loop's steady lag (module docstring)
    "envelope": lambda m: 1.0 / (m.zeta * m.omega_n_rad_s),  # decay time of the response's envelope
    "natural": lambda m: 1.0 / m.omega_n_rad_s,             # 1/ω_n
    "slowest_pole": _slowest_pole_time_s,                   # the dominant real pole (or ζω_n)
    "position_loop": lambda m: 1.0 / m.position_gain_1_s,   # the position loop's 1/k (no K1, K2)
}


def _eq12_peak(lag_s: float, feed_m_s: float, radius_m: float) -> float:
    """Eq. 12 at steady state: ``F T |±cos θ ± sin θ|`` at its peak, ``√2 F T`` [m]."""
    return math.sqrt(2.0) * feed_m_s * lag_s


def _first_order_radius(lag_s: float, feed_m_s: float, radius_m: float) -> float:
    """The radius lost by a circle through a first-order lag: ``R (1 − 1/√(1 + (F T / R)²))`` [m]."""
    return radius_m * (1.0 - 1.0 / math.sqrt(1.0 + (feed_m_s * lag_s / radius_m) ** 2))


#: How Eq. 12's lag becomes a radius error: name -> f(T [s], F [m/s], R [m]) -> m.
LAG_FORMS: dict[str, Callable[[float, float, float], float]] = {
    "eq12_peak": _eq12_peak,
    "first_order_radius": _first_order_radius,
}

#: Eq. 13's divisor per interpolation kind.
INTERPOLATIONS: dict[str, float] = {"exponential": 2.0, "linear": 24.0}

#: How the grid's radius errors become one figure [µm].
AGGREGATES: dict[str, Callable[[np.ndarray], float]] = {
    "sum": lambda e: float(np.sum(e)),
    "mean": lambda e: float(np.mean(e)),
    "max": lambda e: float(np.max(e)),
}


@dataclass(frozen=True)
class Readings:
    """One reading of what the paper leaves open (each field names an entry of its registry)."""

    lag: str = "envelope"
    lag_form: str = "eq12_peak"
    interpolation: str = "exponential"
    aggregate: str = "mean"

    def __post_init__(self) -> None:
        require_choice("lag", self.lag, LAG_READINGS, "readings")
        require_choice("lag_form", self.lag_form, LAG_FORMS, "readings")
        require_choice("interpolation", self.interpolation, INTERPOLATIONS, "readings")
        require_choice("aggregate", self.aggregate, AGGREGATES, "readings")


def mismatch_error_m(model: Paper003Model, feed_m_s: float) -> float:
    """Eq. 8's peak: ``F |1/k_x − 1/k_y| / 2`` [m] (the same size CW and CCW, the sign flips)."""
    return 0.5 * feed_m_s * abs(1.0 / model.position_gain_x_1_s - 1.0 / model.position_gain_y_1_s)


def interpolation_error_m(model: Paper003Model, feed_m_s: float, radius_m: float, interpolation: str) -> float:
    """Eq. 13: ``T_ip² F² / (d R)``, d = 2 (exponential) or 24 (linear) [m]."""
    return model.t_ip_s ** 2 * feed_m_s ** 2 / (INTERPOLATIONS[interpolation] * radius_m)


def radius_error_m(model: Paper003Model, feed_m_s: float, radius_m: float, readings: Readings) -> float:
    """Eq. 17's objective at one circle: mismatch + servo lag + interpolation [m]."""
    lag_s = LAG_READINGS[readings.lag](model)
    return (mismatch_error_m(model, feed_m_s)
            + LAG_FORMS[readings.lag_form](lag_s, feed_m_s, radius_m)
            + interpolation_error_m(model, feed_m_s, radius_m, readings.interpolation))


def grid_errors_um(model: Paper003Model, readings: Readings) -> np.ndarray:
    """Radius errors over the paper's grid, shape (feeds, radii, directions) [µm]."""
    errors = [[[radius_error_m(model, f / 60000.0, r / 1000.0, readings) for _ in GRID_DIRECTIONS]
               for r in GRID_RADII_MM] for f in GRID_FEEDS_MM_MIN]
    return np.asarray(errors) * UM_PER_M


def objective_um(model: Paper003Model, readings: Readings) -> float:
    """Eq. 17 aggregated over the grid as ``readings.aggregate`` says [µm]."""
    return AGGREGATES[readings.aggregate](grid_errors_um(model, readings))


def loop_radius_error_m(model: Paper003Model, feed_m_s: float, radius_m: float) -> float:
    """Steady radius lost by the closed position loop on a circle: ``R (1 − |T(jω)|)``, ``ω = F/R`` [m].

    ``T = k H / (s + k H)`` (continuous, equal gains on both axes): a linear,
    isotropic loop turns the circle into a circle of radius ``R |T(jω)|``.
    This is the physical radius reduction of the model, with no reading needed.
    """
    loop = model.position_gain_1_s * velocity_loop(model) * control.tf([1.0], [1.0, 0.0])
    gain = abs(complex(control.feedback(loop, 1)(1j * feed_m_s / radius_m)))
    return radius_m * (1.0 - gain)


def loop_grid_error_um(model: Paper003Model) -> float:
    """Mean of :func:`loop_radius_error_m` over the paper's grid (both directions alike) [µm]."""
    errors = [loop_radius_error_m(model, f / 60000.0, r / 1000.0) for f in GRID_FEEDS_MM_MIN for r in GRID_RADII_MM]
    return float(np.mean(errors)) * UM_PER_M


def model_of_column(column: str, base: Paper003Model | None = None) -> Paper003Model:
    """The model with a Table 2 column's K1, K2 (other fields from ``base``)."""
    require_choice("column", column, PAPER003_TABLE, "paper003")
    row = PAPER003_TABLE[column]
    return (base or Paper003Model()).with_(k1=row.k1, k2=row.k2)
