"""Koren's cross-coupled controller (CCC): a PID on the contour error, distributed to the axes.

Per tick, with ε_c from the estimator (> 0 to the left of travel) and θ the
local direction of travel::

    v      = K_p ε_c + K_i Σ ε_c Δt + K_d (ε_c(t) − ε_c(t−1))/Δt      drive units (integral clamped)
    C      = (−sin θ, cos θ)                                           the left normal: ε_c ≈ C·(P − P*)
    corr_i = −C_i · v · g_i                                            axes 1 and 2; 0 on the others

so a positive ε_c is pushed back to the right along the normal. ``g_i``
(``axis_gains``) scales each axis (empty: 1).

**Gains for a circle.** Koren's variable-gain CCC computes ε_c from the
axis following errors, which on a circle of radius R needs the curvature:
ε ≈ −e_x C_x' + e_y C_y' with C_x' = sin θ − e_x/(2R), C_y' = cos θ + e_y/(2R)
(to first order). Here ε_c comes from the estimator, exact to its own
accuracy, so the gains only give the direction of the correction; we use the
local normal alone. The dropped curvature terms are of relative size e/(2R)
(10 µm on R = 10 mm: 5e-4).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from cnc_contour_control.compensators.base import MAX_GAIN, AxisCorrection, CompensatorSample, check_sample, factors_for
from cnc_contour_control.compensators.state_file import load_state, save_state
from cnc_contour_control.core.params import param

_WHO = "ccc compensator"
#: Largest gain a config accepts (any unit).


@dataclass(frozen=True)
class CrossCoupledConfig(AxisCorrection):
    """Gains of the cross-coupled controller (defaults sized for paper 000's DAC drives: 1 BLU = 10 µm).

    Parameters
    ----------
    kp : float
        Proportional gain on ε_c [drive units per m], in [0, 1e12].
    ki : float
        Integral gain [drive units per m·s], in [0, 1e12].
    kd : float
        Derivative gain [drive units · s per m], in [0, 1e12].
    integral_limit : float
        Clamp of the integral term [drive units], in [0, 1e12].
    axis_gains, output_limit
        As :class:`~cnc_contour_control.compensators.base.AxisCorrection`.
    """

    kp: float = param(2.0e5, unit="drive/m", low=0.0, high=MAX_GAIN,
                      description="proportional gain on the contour error")
    ki: float = param(2.0e6, unit="drive/(m*s)", low=0.0, high=MAX_GAIN,
                      description="integral gain on the contour error")
    kd: float = param(0.0, unit="drive*s/m", low=0.0, high=MAX_GAIN, description="derivative gain on the contour error")
    integral_limit: float = param(50.0, unit="drive", low=0.0, high=MAX_GAIN,
                                  description="clamp of the integral term (anti-windup)")

    def __post_init__(self) -> None:
        self.check("ccc")


class CrossCoupledCompensator:
    """Koren's cross-coupled controller on the estimator's ε_c (see the module docstring).

    It learns nothing: ``frozen`` changes nothing, ``end_run`` does nothing.

    Parameters
    ----------
    config : CrossCoupledConfig
        Validated gains.
    axis_names : sequence of str
        The axes; the first two span the contour plane.
    """

    def __init__(self, config: CrossCoupledConfig, axis_names: Sequence[str]) -> None:
        self.config = config
        self.axis_names = tuple(axis_names)
        self._gains = factors_for("axis_gains", config.axis_gains, self.axis_names, "ccc")
        self.frozen = False
        self.fault: str | None = None
        self._zeros = [0.0] * len(self.axis_names)
        self.reset()

    def reset(self) -> None:
        """Zero the integral and forget ε_c(t−1)."""
        self._integral = 0.0
        self._previous: float | None = None

    def step(self, sample: CompensatorSample) -> list[float]:
        """The correction per axis [drive units] for ``sample`` (a fresh list)."""
        check_sample(_WHO, sample, self.axis_names)
        config, error, dt_s = self.config, sample.contour_error_m, sample.dt_s
        limit = config.integral_limit
        integral = self._integral + config.ki * error * dt_s
        self._integral = integral = -limit if integral < -limit else (limit if integral > limit else integral)
        rate = 0.0 if self._previous is None else (error - self._previous) / dt_s
        self._previous = error
        push = config.kp * error + integral + config.kd * rate
        normal = (-math.sin(sample.angle_rad), math.cos(sample.angle_rad))
        out, clip = self._zeros[:], config.output_limit
        for k in range(min(2, len(out))):
            value = -normal[k] * push * self._gains[k]
            out[k] = -clip if value < -clip else (clip if value > clip else value)
        return out

    def end_run(self) -> None:
        """Nothing: the CCC does not learn."""

    def save(self, path: str | Path) -> None:
        """Write an empty state file (the CCC learns nothing)."""
        save_state(path, {})

    def load(self, path: str | Path) -> None:
        """Check ``path`` is a numeric ``.npz`` without arrays (the CCC learns nothing)."""
        load_state(path, {}, f"{_WHO} state")
