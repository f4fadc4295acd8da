"""Closed velocity loops as the position loop sees them: velocity command -> axis velocity (ROS-free).

Papers 002 and 003 close a PI velocity loop over the motor and a P position
loop around it. The position loop's "plant" is the closed velocity loop

    P(s) = (K_t K_sp s + K_t K_si) / (J s² + K_t K_sp s + K_t K_si)

(paper 002's names; paper 003 writes K2 = K_sp, K1 = K_si, K_t/J_m = 157),
unit DC gain, from the velocity command to the axis velocity in the same
unit. Paper 002 also gives the loops it identified on its machine at 1 kHz
(Eqs. 35, 36), :data:`PAPER002_MODELS`. The plant (``cnc_plant_sim``) and
the disturbance-rejecting laws (their nominal model P_n) both take their
models from here, so the paper's numbers live in one place.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from scipy import signal

from cnc_contour_control.core.config import require_finite, require_range
from cnc_contour_control.core.errors import ConfigError


@dataclass(frozen=True)
class DiscreteVelocityModel:
    """A closed velocity loop as a discrete transfer function in z⁻¹ at ``sample_time_s``.

    Attributes
    ----------
    numerator : tuple of float
        b_0 + b_1 z⁻¹ + ... (velocity command -> velocity).
    denominator : tuple of float
        1 + a_1 z⁻¹ + ... (a_0 must be 1).
    sample_time_s : float
        The sample time the coefficients belong to [s].
    """

    numerator: tuple[float, ...]
    denominator: tuple[float, ...]
    sample_time_s: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "numerator", tuple(float(b) for b in self.numerator))
        object.__setattr__(self, "denominator", tuple(float(a) for a in self.denominator))
        for name, values in (("numerator", self.numerator), ("denominator", self.denominator)):
            if not values:
                raise ConfigError(f"{name} must have at least one coefficient")
            for i, value in enumerate(values):
                require_finite(f"{name}[{i}]", value)
        if self.denominator[0] != 1.0:
            raise ConfigError(f"denominator[0] must be 1 (monic in z⁻¹), got {self.denominator[0]}")
        require_range("sample_time_s", self.sample_time_s, 1e-6, 1.0)

    def dlti(self) -> signal.dlti:
        """The model as a :class:`scipy.signal.dlti` (z-domain, ``dt = sample_time_s``).

        Both coefficient lists are padded to one length, so they read as
        polynomials in z over the same power: the z⁻¹ form above.
        """
        from scipy import signal
        n = max(len(self.numerator), len(self.denominator))
        num = np.pad(self.numerator, (0, n - len(self.numerator)))
        den = np.pad(self.denominator, (0, n - len(self.denominator)))
        return signal.dlti(np.trim_zeros(num, "f"), den, dt=self.sample_time_s)  # (leading zeros: a pure delay)


@dataclass(frozen=True)
class PiVelocityLoop:
    """A PI velocity loop over a rigid motor, in continuous time (paper 002 Fig. 2, paper 003 Eq. 1).

    Attributes
    ----------
    torque_per_inertia : float
        K_t / J [rad/(s² · unit)] (paper 003: ≈ 157).
    kp : float
        Proportional gain K_sp (paper 003's K2) [per the paper's unit].
    ki : float
        Integral gain K_si (paper 003's K1).
    """

    torque_per_inertia: float
    kp: float
    ki: float

    def __post_init__(self) -> None:
        require_range("torque_per_inertia", self.torque_per_inertia, 1e-6, 1e9)
        require_range("kp", self.kp, 0.0, 1e9)
        require_range("ki", self.ki, 1e-12, 1e12)

    def natural_frequency_rad_s(self) -> float:
        """ω_n = √(K_si K_t / J) [rad/s]."""
        return math.sqrt(self.ki * self.torque_per_inertia)

    def damping(self) -> float:
        """ζ = K_sp K_t / (2 ω_n J)."""
        return self.kp * self.torque_per_inertia / (2.0 * self.natural_frequency_rad_s())

    def lti(self) -> signal.lti:
        """The closed loop (velocity command -> velocity) as a :class:`scipy.signal.lti`."""
        from scipy import signal
        c = self.torque_per_inertia
        return signal.lti([c * self.kp, c * self.ki], [1.0, c * self.kp, c * self.ki])


#: Paper 002's identified closed velocity loops at 1 kHz (Eqs. 35 and 36), per axis.
PAPER002_MODELS: dict[str, DiscreteVelocityModel] = {
    "x": DiscreteVelocityModel((0.0, 0.1894, -0.1866), (1.0, -1.8106, 0.8134), 0.001),
    "y": DiscreteVelocityModel((0.0, 0.1425, -0.1404), (1.0, -1.8575, 0.8596), 0.001),
}

#: Paper 003's K_t / J_m (both columns of its table give ≈ 157).
PAPER003_TORQUE_PER_INERTIA = 157.0
