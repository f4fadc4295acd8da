"""Radius reduction of a circular test: measured, and predicted from servo lag and accel/decel (paper 003, Eqs. 12-13).

A linear axis pair following a circle of radius R at feed F (ω = F/R) traces,
after the start transient, a circle of radius ``R |G(jω)|``, G the chain from
reference to position. Paper 003 splits the loss into

- servo lag (Eq. 12): a P position loop of gain k over a velocity-commanded
  axis is the first-order lag ``G_s = (ff·s + k)/(s + k)`` (ff the velocity
  feedforward share, 0 without), so ``ΔR_s = R (1 - |G_s(jω)|)``, which for
  ``ff = 0`` and ``ωT << 1`` (T = 1/k) is ``F² T²/(2R)``;
- acceleration/deceleration after interpolation (Eq. 13): an exponential
  filter is the first-order lag ``1/(1 + T_ip s)``, a linear one the moving
  average of length T_ip, ``|sin(ωT_ip/2)/(ωT_ip/2)|``; Eq. 13's
  ``T_ip² F²/(2R)`` and ``T_ip² F²/(24R)`` are their small-ωT forms.

:func:`predict_radius_loss` gives both parts, Eq. 13's own value and the
product of the chains; :func:`measured_radius_loss_um` the trace's mean
``R - |p - c|``. The velocity loop inside the axis (paper 003's K1, K2) adds
no steady lag of its own (a PI loop has unit DC gain) and is left out: its
share is what the measured figure shows beyond the prediction.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cnc_contour_control.core.config import require_choice, require_non_negative, require_positive
from cnc_tools.analysis.ballbar import CircleTrace

M_TO_UM = 1e6


def _exponential(omega_t: float) -> float:
    return 1.0 / math.sqrt(1.0 + omega_t * omega_t)


def _linear(omega_t: float) -> float:
    half = 0.5 * omega_t
    return 1.0 if half == 0.0 else abs(math.sin(half) / half)


#: The gain of the accel/decel filter at ωT_ip, and Eq. 13's divisor, per kind.
ACCEL_DECEL_KINDS: dict[str, tuple[Any, float]] = {
    "none": (lambda omega_t: 1.0, math.inf),
    "exponential": (_exponential, 2.0),
    "linear": (_linear, 24.0),
}


@dataclass(frozen=True)
class RadiusLossModel:
    """What the prediction needs: the position loop and the accel/decel filter.

    Attributes
    ----------
    position_gain_per_s : float or None
        k of a P position loop over a velocity-commanded axis [1/s]; None when
        the run's servo is not one (its lag is then not predicted).
    feedforward : float
        Velocity feedforward share, 0..1 (the servo's ff1 on such an axis).
    accel_decel_kind : str
        ``none``, ``exponential`` or ``linear``.
    accel_decel_time_constant_s : float
        T_ip [s].
    skipped : str
        Why the servo lag is not predicted ("" when it is).
    """

    position_gain_per_s: float | None
    feedforward: float = 0.0
    accel_decel_kind: str = "none"
    accel_decel_time_constant_s: float = 0.0
    skipped: str = ""

    def __post_init__(self) -> None:
        if self.position_gain_per_s is not None:
            require_positive("position_gain_per_s", self.position_gain_per_s)
        require_choice("accel_decel_kind", self.accel_decel_kind, ACCEL_DECEL_KINDS)
        require_non_negative("accel_decel_time_constant_s", self.accel_decel_time_constant_s)


@dataclass(frozen=True)
class RadiusLoss:
    """The predicted radius reduction of one circle [µm] (None: not predicted, see ``skipped``)."""

    servo_lag_um: float | None
    accel_decel_um: float
    accel_decel_eq13_um: float
    total_um: float | None
    skipped: str


def predict_radius_loss(model: RadiusLossModel, feed_m_s: float, radius_m: float) -> RadiusLoss:
    """The steady radius reduction at ``feed_m_s`` on ``radius_m`` from servo lag and accel/decel."""
    omega = require_positive("feed_m_s", feed_m_s) / require_positive("radius_m", radius_m)
    gain_of, divisor = ACCEL_DECEL_KINDS[model.accel_decel_kind]
    t_ip = model.accel_decel_time_constant_s
    filter_gain = gain_of(omega * t_ip)
    eq13_m = t_ip * t_ip * feed_m_s * feed_m_s / (divisor * radius_m)
    accel_decel_um = radius_m * (1.0 - filter_gain) * M_TO_UM
    if model.position_gain_per_s is None:
        return RadiusLoss(None, accel_decel_um, eq13_m * M_TO_UM, None, model.skipped)
    k, ff = model.position_gain_per_s, model.feedforward
    servo_gain = math.hypot(ff * omega, k) / math.hypot(omega, k)
    return RadiusLoss(radius_m * (1.0 - servo_gain) * M_TO_UM, accel_decel_um, eq13_m * M_TO_UM,
                      radius_m * (1.0 - servo_gain * filter_gain) * M_TO_UM, "")


def measured_radius_loss_um(trace: CircleTrace) -> float:
    """The trace's mean ``R - |p - c|`` [µm] (positive: the circle came out small)."""
    radii = np.hypot(*(trace.points_m - np.asarray(trace.center_m)).T)
    return float(trace.radius_m - radii.mean()) * M_TO_UM


#: Plant models whose axes take a velocity command, so that a ``p`` servo law is Eq. 12's position loop.
VELOCITY_COMMANDED = ("paper002", "paper003")


def model_from_scenario(scenario: Mapping[str, Any]) -> RadiusLossModel:
    """The prediction's inputs from a run's scenario mapping (``scenario.yaml`` beside the bag)."""
    interp = (scenario.get("interpolator") or {}).get("accel_decel") or {}
    kind, t_ip = str(interp.get("kind", "none")), float(interp.get("time_constant_s", 0.0) or 0.0)
    servo = scenario.get("servo") or {}
    plant = str((scenario.get("plant") or {}).get("model", "paper000"))
    if servo.get("law") != "p" or plant not in VELOCITY_COMMANDED:
        reason = (f"servo_lag_um: needs law p on a velocity-commanded plant {VELOCITY_COMMANDED}, "
                  f"got law {servo.get('law')!r} on {plant!r}")
        return RadiusLossModel(None, 0.0, kind, t_ip, reason)
    if servo.get("axes"):
        return RadiusLossModel(None, 0.0, kind, t_ip, "servo_lag_um: the axes have their own gains (a mismatch)")
    counts_per_m = float(servo.get("counts_per_m", 1.0e5))  # the command is m/s: k = kp · counts_per_m
    k = float((servo.get("law_params") or {}).get("kp", 0.0)) * counts_per_m
    if k <= 0.0:
        return RadiusLossModel(None, 0.0, kind, t_ip, f"servo_lag_um: needs law_params.kp > 0, got k = {k}")
    return RadiusLossModel(k, float(servo.get("ff1", 0.0)) * counts_per_m, kind, t_ip)
