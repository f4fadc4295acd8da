"""The linear loop of a PDC stacked on a drive-input law (PID), built with python-control (ROS-free).

Signals (law units: position in counts, velocity in counts/s, commands in drive units)::

    y = P_v (v + d),  x = P_x (v + d)     the plant: drive input plus input load -> velocity, position
    e = r − x,  u = C e                   the inner law (PID: :func:`pid_transfer`)
    T_E = H (y − P_n v)                   the PDC, when used
    v = u − T_E

P_v and P_x are the true plant's sampled velocity and position responses
(ZOH, as the servo holds its command), P_n the canceller's model; the loop is
interconnected without minimisation (:func:`control.interconnect`), so
:func:`~cnc_contour_control.disturbance.loop.is_stable` is internal stability.
:func:`stack_figures` gives, as :func:`~cnc_contour_control.laws.loop_report.
loop_figures` does for paper 002's cascade: |S|∞ (S = e/r), the disturbance
peak (max |x/d| with the PDC over |x/d| without) and the removal at f_d,
Eq. 13's margin max |H P_n Δ| with Δ = P_v/P_n − 1 (< 1 required) and
max |H P_n| (how far the canceller's gain reaches beyond f_d). With P_v =
P_n the PDC leaves S unchanged (T_E = H P_n d does not see r); a model error
brings H into the loop, which is why |S|∞ and Eq. 13 are taken on the drawn plant.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import control
import numpy as np
from scipy import signal

from cnc_contour_control.disturbance.design import response
from cnc_contour_control.disturbance.loop import Tf, frequency_grid_hz, is_stable, responses, tf


def pid_transfer(kp: float, ki_per_s: float, kd_s: float, sample_time_s: float) -> Tf:
    """The incremental PID of :mod:`~cnc_contour_control.laws.pid` as C(z⁻¹) (no clamp).

    u(k) − u(k−1) = K_p (e − e₁) + K_i T e + (K_d/T)(e − 2e₁ + e₂)
    """
    t = sample_time_s
    numerator = np.array([kp + ki_per_s * t + kd_s / t, -kp - 2.0 * kd_s / t, kd_s / t])
    return numerator, np.array([1.0, -1.0])


@dataclass(frozen=True)
class StackBlocks:
    """The blocks of one stack in z⁻¹ (``h`` None: the inner law alone).

    Attributes
    ----------
    velocity, position : Tf
        The true plant: drive input -> velocity [counts/s], -> position [counts].
    model : Tf
        P_n: drive input -> velocity [counts/s].
    controller : Tf
        C: error [counts] -> command [drive units].
    sample_time_s : float
        T [s].
    h : Tf or None
        The PDC's H.
    """

    velocity: Tf
    position: Tf
    model: Tf
    controller: Tf
    sample_time_s: float
    h: Tf | None = None


def _system(block: Tf, dt: float, inputs: str, outputs: str, name: str) -> control.TransferFunction:
    b, a = block
    n = max(len(a), len(b))
    return control.tf(np.pad(b, (0, n - len(b))), np.pad(a, (0, n - len(a))), dt, inputs=inputs, outputs=outputs,
                      name=name)


def stack_loop(blocks: StackBlocks) -> control.InputOutputSystem:
    """The loop from (r, d) to (x, e) as one discrete state-space system (all internal modes kept)."""
    dt = blocks.sample_time_s
    systems = [control.summing_junction(["v", "d"], "pin", name="plant_input"),
               _system(blocks.velocity, dt, "pin", "y", "plant_v"),
               _system(blocks.position, dt, "pin", "x", "plant_x"),
               control.summing_junction(["r", "-x"], "e", name="error"),
               _system(blocks.controller, dt, "e", "u", "law")]
    if blocks.h is None:
        systems.append(control.summing_junction(["u"], "v", name="command"))
    else:
        systems += [_system(blocks.model, dt, "v", "yn", "model"),
                    control.summing_junction(["y", "-yn"], "res", name="residual"),
                    _system(blocks.h, dt, "res", "te", "h"),
                    control.summing_junction(["u", "-te"], "v", name="command")]
    return control.interconnect(systems, inplist=["r", "d"], outlist=["x", "e"], check_unused=False)


def stack_figures(blocks: StackBlocks, f_d_hz: float, points: int = 2000) -> dict[str, float | bool]:
    """Stability, |S|∞, the disturbance peak (over the law alone), the removal at ``f_d_hz`` and Eq. 13's margin."""
    if blocks.h is None:
        raise ValueError("stack_figures needs a PDC (blocks.h)")
    dt = blocks.sample_time_s
    f = frequency_grid_hz(dt, points)
    grid = np.append(f, f_d_hz)
    system, alone = stack_loop(blocks), stack_loop(replace(blocks, h=None))
    with_pdc, bare = responses(system, grid), responses(alone, grid)
    ratio = with_pdc[0, 1] / bare[0, 1]
    pn = response(*blocks.model, f, dt)
    delta = response(*blocks.velocity, f, dt) / pn - 1.0
    hp = response(blocks.h[0], [1.0], f, dt) * pn
    return {"stable": is_stable(system), "stable_without": is_stable(alone),
            "sensitivity_peak": float(np.max(np.abs(with_pdc[1, 0, :-1]))),
            "sensitivity_peak_without": float(np.max(np.abs(bare[1, 0, :-1]))),
            "disturbance_peak": float(np.max(np.abs(ratio[:-1]))),
            "disturbance_peak_hz": float(f[int(np.argmax(np.abs(ratio[:-1])))]),
            "removal_at_fd": float(1.0 - abs(ratio[-1])),
            "eq13_margin": float(np.max(np.abs(hp * delta))), "hp_peak": float(np.max(np.abs(hp)))}


def zoh_model(numerator_s: Sequence[float], denominator_s: Sequence[float], gain: float, sample_time_s: float) -> Tf:
    """``gain`` · P(s) (polynomials in s, highest power first) held by a ZOH at ``sample_time_s``, in z⁻¹.

    :func:`scipy.signal.cont2discrete`; the exact leading zero of a strictly proper P is set to 0, a_0 to 1.
    """
    b, a, _ = signal.cont2discrete(([v * gain for v in numerator_s], list(denominator_s)), sample_time_s,
                                   method="zoh")
    b, a = np.ravel(b), np.ravel(a)
    b[np.abs(b) < 1e-12 * np.max(np.abs(b))] = 0.0
    return tf(b / a[0], a / a[0])


def sampled_plant(numerator_s: Sequence[float], denominator_s: Sequence[float], counts_per_m: float,
                  sample_time_s: float) -> tuple[Tf, Tf]:
    """(velocity, position) in z⁻¹ of P(s) [m/s per drive unit], ZOH at ``sample_time_s``, in counts."""
    return (zoh_model(numerator_s, denominator_s, counts_per_m, sample_time_s),
            zoh_model(numerator_s, [*denominator_s, 0.0], counts_per_m, sample_time_s))
