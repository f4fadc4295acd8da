"""Paper 000's incremental (velocity-form) PID with gains in time units, and a pure P law.

Eq. (14) of paper 000, discretised with the sample's own period ``T_k = dt_s``::

    r(k) = [e(k) − e(k−1)] / T_k                                  (error rate)
    u(k) = u(k−1) + K_p·[e(k) − e(k−1)] + K_i·T_k·e(k) + K_d·[r(k) − r(k−1)]

The gains are continuous-time: ``K_p`` [drive units/count], ``K_i`` [1/s ·
K_p's unit], ``K_d`` [s · K_p's unit], so a scenario with another sample
time keeps the same loop. ``u(k)`` is clamped to ``±state_limit`` before it
is stored (the velocity form's anti-windup). Errors in counts (BLU for paper
000), output in drive units (DAC).

Paper 000's Table 4 gives per-sample gains (``Kp = 2.4``, ``Ki = 0.1``,
``Kd = 6.7`` at T = 10 ms, with ``T`` folded into ``Ki`` and ``Kd``).
:func:`pid_gains_from_per_sample` converts them: ``K_i = Ki/T = 10 /s``,
``K_d = Kd·T = 0.067 s``; at T = 10 ms the law above is then Eq. (14) with
the paper's numbers, to rounding. :func:`pid_gains_per_sample` goes back.
"""
from __future__ import annotations

from dataclasses import dataclass

from cnc_contour_control.core.config import require_positive
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.laws.base import LawOutput, LawSample, require_config

#: Largest gain a config accepts (any unit).
MAX_GAIN = 1.0e6
#: Range of the PID's state clamp [drive units].
STATE_LIMIT_RANGE = (1.0e-9, 1.0e12)


def pid_gains_from_per_sample(kp: float, ki: float, kd: float, sample_time_s: float) -> dict[str, float]:
    """Per-sample gains of Eq. (14) at ``sample_time_s`` [s] to this law's time-unit gains.

    ``kp`` stays, ``ki/T`` [1/s], ``kd·T`` [s]. Paper 000's Table 4 (2.4, 0.1,
    6.7 at T = 0.01 s) gives ``{"kp": 2.4, "ki": 10.0, "kd": 0.067}``.
    """
    period = require_positive("sample_time_s", sample_time_s)
    return {"kp": float(kp), "ki": float(ki) / period, "kd": float(kd) * period}


def pid_gains_per_sample(kp: float, ki: float, kd: float, sample_time_s: float) -> dict[str, float]:
    """Time-unit gains to Eq. (14)'s per-sample gains at ``sample_time_s`` [s]: ``kp``, ``ki·T``, ``kd/T``."""
    period = require_positive("sample_time_s", sample_time_s)
    return {"kp": float(kp), "ki": float(ki) * period, "kd": float(kd) / period}


@dataclass(frozen=True)
class PidConfig:
    """Gains of the incremental PID in time units (defaults: paper 000's Table 4 at T = 10 ms).

    Parameters
    ----------
    kp : float
        Proportional gain K_p [drive units per count], in [0, 1e6].
    ki : float
        Integral gain K_i [drive units per count-second], in [0, 1e6].
    kd : float
        Derivative gain K_d [drive units per count/s], in [0, 1e6].
    state_limit : float
        Clamp of the stored output u(k) [drive units], in [1e-9, 1e12].
    """

    kp: float = param(2.4, unit="drive/count", low=0.0, high=MAX_GAIN,
                      description="proportional gain K_p")
    ki: float = param(10.0, unit="drive/(count*s)", low=0.0, high=MAX_GAIN,
                      description="integral gain K_i (per second; Table 4's 0.1 per sample at T = 10 ms is 10)")
    kd: float = param(0.067, unit="drive*s/count", low=0.0, high=MAX_GAIN,
                      description="derivative gain K_d (seconds; Table 4's 6.7 per sample at T = 10 ms is 0.067)")
    state_limit: float = param(127.0, unit="drive", low=STATE_LIMIT_RANGE[0], high=STATE_LIMIT_RANGE[1],
                               description="clamp of the stored output u(k) (anti-windup)")

    def __post_init__(self) -> None:
        check_ranges(self, "pid")


class PidLaw:
    """Incremental PID, Eq. (14) of paper 000 in time units, with a clamped state."""

    def __init__(self, config: PidConfig) -> None:
        self.output = LawOutput()
        self.retune(config)
        self.reset()

    def retune(self, config: PidConfig) -> None:
        """Swap the gains, keeping u(k−1), e(k−1) and r(k−1) (bumpless: the velocity form)."""
        self.config = require_config("pid", config, PidConfig)
        self._kp, self._ki, self._kd = config.kp, config.ki, config.kd
        self._limit = config.state_limit

    def reset(self) -> None:
        """Zero u(k−1), e(k−1) and the error rate r(k−1)."""
        self._u = 0.0
        self._e1 = 0.0
        self._rate1 = 0.0

    def step(self, sample: LawSample) -> LawOutput:
        """u(k) for ``sample.error_counts`` over ``sample.dt_s``."""
        error, dt_s = sample.error_counts, sample.dt_s
        change = error - self._e1
        rate = change / dt_s
        u = self._u + self._kp * change + self._ki * dt_s * error + self._kd * (rate - self._rate1)
        limit = self._limit
        u = -limit if u < -limit else (limit if u > limit else u)
        self._u, self._e1, self._rate1 = u, error, rate
        out = self.output
        out.feedback = u
        return out


@dataclass(frozen=True)
class PConfig:
    """Gain of the pure proportional law.

    Parameters
    ----------
    kp : float
        Proportional gain [drive units per count], in [0, 1e6].
    """

    kp: float = param(2.4, unit="drive/count", low=0.0, high=MAX_GAIN, description="proportional gain K_p")

    def __post_init__(self) -> None:
        check_ranges(self, "p")


class PLaw:
    """Pure proportional law ``u = kp·e`` (used for friction identification)."""

    def __init__(self, config: PConfig) -> None:
        self.output = LawOutput()
        self.retune(config)

    def retune(self, config: PConfig) -> None:
        """Swap the gain (the law has no state)."""
        self.config = require_config("p", config, PConfig)
        self._kp = config.kp

    def reset(self) -> None:
        """Nothing to reset (stateless)."""

    def step(self, sample: LawSample) -> LawOutput:
        """``kp·error``."""
        out = self.output
        out.feedback = self._kp * sample.error_counts
        return out
