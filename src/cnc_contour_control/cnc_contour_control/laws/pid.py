"""Paper 000's incremental (velocity-form) PID and a pure P law.

Eq. (14)::

    u(k) = u(k−1) + Kp·[e(k) − e(k−1)] + Ki·e(k) + Kd·[e(k) − 2e(k−1) + e(k−2)]

The gains are per sample (Ki and Kd include the sample time T), so ``dt_s``
is not used: retune the gains when T changes. ``u(k)`` is clamped to
``±state_limit`` before it is stored, which is the anti-windup of the
velocity form. Errors in BLU, output in DAC units for paper 000
(Table 4: Kp = 2.4, Ki = 0.1, Kd = 6.7).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.config import build_config, require_non_negative, require_positive
from cnc_contour_control.laws.registry import register_law


@dataclass(frozen=True)
class PidConfig:
    """Gains of the incremental PID.

    Parameters
    ----------
    kp : float
        Proportional gain [drive units per length unit], >= 0.
    ki : float
        Integral gain per sample (includes T), >= 0.
    kd : float
        Derivative gain per sample (includes 1/T), >= 0.
    state_limit : float
        Clamp of the stored output u(k) [drive units], > 0.
    """

    kp: float = 2.4
    ki: float = 0.1
    kd: float = 6.7
    state_limit: float = 127.0

    def __post_init__(self) -> None:
        for name in ("kp", "ki", "kd"):
            require_non_negative(name, getattr(self, name), context="pid")
        require_positive("state_limit", self.state_limit, context="pid")


class PidLaw:
    """Incremental PID, Eq. (14) of paper 000, with a clamped state."""

    def __init__(self, config: PidConfig) -> None:
        self.config = config
        self._kp, self._ki, self._kd = float(config.kp), float(config.ki), float(config.kd)
        self._limit = float(config.state_limit)
        self.reset()

    def reset(self) -> None:
        """Zero u(k−1), e(k−1) and e(k−2)."""
        self._u = 0.0
        self._e1 = 0.0
        self._e2 = 0.0

    def step(self, error: float, dt_s: float) -> float:
        """u(k) for ``error`` e(k) [length units]; ``dt_s`` is unused (gains per sample)."""
        e1, e2 = self._e1, self._e2
        u = (self._u + self._kp * (error - e1) + self._ki * error
             + self._kd * (error - 2.0 * e1 + e2))
        limit = self._limit
        u = -limit if u < -limit else (limit if u > limit else u)
        self._u, self._e1, self._e2 = u, error, e1
        return u


@dataclass(frozen=True)
class PConfig:
    """Gain of the pure proportional law.

    Parameters
    ----------
    kp : float
        Proportional gain [drive units per length unit], >= 0.
    """

    kp: float = 2.4

    def __post_init__(self) -> None:
        require_non_negative("kp", self.kp, context="p")


class PLaw:
    """Pure proportional law ``u = kp·e`` (used for friction identification)."""

    def __init__(self, config: PConfig) -> None:
        self.config = config
        self._kp = float(config.kp)

    def reset(self) -> None:
        """Nothing to reset (stateless)."""

    def step(self, error: float, dt_s: float) -> float:
        """``kp·error``; ``dt_s`` is unused."""
        return self._kp * error


@register_law("pid")
def make_pid(params: Mapping[str, Any]) -> PidLaw:
    """The incremental PID from params ``kp``, ``ki``, ``kd``, ``state_limit``."""
    return PidLaw(build_config(PidConfig, params, context="pid"))


@register_law("p")
def make_p(params: Mapping[str, Any]) -> PLaw:
    """The P law from params ``kp``."""
    return PLaw(build_config(PConfig, params, context="p"))
