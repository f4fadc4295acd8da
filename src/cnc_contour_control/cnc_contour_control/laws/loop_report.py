"""Design checks of paper 002's laws as plain values, for tests and ``cnc-contour bench paper002`` (ROS-free).

:func:`design_report` takes one law config per combination (the registry's
``dob``, ``mbda``, ``pdc``, ``dob_pdc``, ``mbda_pdc`` configs, or ``p``'s
gain for none) and returns, per combination and per inertia error ε of
the plant (P from :func:`~cnc_contour_control.disturbance.loop.
inertia_perturbed`):

* ``stable``: the closed loop's characteristic polynomial;
* ``sensitivity_peak``: max |S| of the position loop, S = e/r;
* ``disturbance_peak``: max over frequency of |x/d| with the path over
  |x/d| without any (the P loop alone): how much any band of an input
  disturbance is amplified (≤ 2: no band by more than 6 dB);
* ``removal_at_fd``: 1 − that ratio at f_d (the share of the f_d component
  removed);

and for a PDC design: H·P_n at f_d (gain, phase), M_L, W, and the robust-
stability margin of Eq. 13, max_f |H P_n|·|Δ| (< 1 required) for
Δ = P/P_n − 1 at each ε.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from cnc_contour_control.disturbance.design import bode_phase_deg, dob_filters, mbda_pi, response
from cnc_contour_control.disturbance.loop import (
    GRID_POINTS,
    LoopBlocks,
    closed_loop,
    frequency_grid_hz,
    inertia_perturbed,
    is_stable,
    responses,
    tf,
)
from cnc_contour_control.laws.disturbance import DobConfig, MbdaConfig, PdcConfig, PositionLoopConfig

#: Inertia errors ε reported by default (plant inertia (1 + ε)·J).
INERTIA_ERRORS = (0.0, -0.2, 0.2)


def loop_blocks(config: PositionLoopConfig, inertia_error: float = 0.0) -> LoopBlocks:
    """The linear loop of ``config``'s law around a plant with inertia error ``inertia_error``."""
    model = config.nominal()
    pn = tf(model.numerator, model.denominator)
    parts: dict[str, Any] = {}
    if isinstance(config, PdcConfig):
        parts["h"] = tf(config.pdc_design().h)
    if isinstance(config, DobConfig):
        q = config.q_design()
        inverse, _ = dob_filters(q, model)
        parts["q"], parts["q_inverse_model"] = tf(*q), tf(*inverse)
    if isinstance(config, MbdaConfig):
        parts["m"] = tf(*mbda_pi(config.mbda_kp, config.mbda_ki, model.sample_time_s))
    return LoopBlocks(inertia_perturbed(pn, inertia_error), pn, config.kp, model.sample_time_s, **parts)


def _bare(config: PositionLoopConfig, inertia_error: float) -> LoopBlocks:
    """The P loop alone on the same plant."""
    model = config.nominal()
    pn = tf(model.numerator, model.denominator)
    return LoopBlocks(inertia_perturbed(pn, inertia_error), pn, config.kp, model.sample_time_s)


def loop_figures(config: PositionLoopConfig, f_d_hz: float, inertia_error: float = 0.0,
                 points: int = GRID_POINTS) -> dict[str, float | bool]:
    """Stability, |S|∞, the disturbance peak and the removal at ``f_d_hz`` of one combination (plain values)."""
    system = closed_loop(loop_blocks(config, inertia_error))
    f = frequency_grid_hz(config.nominal().sample_time_s, points)
    grid = np.append(f, f_d_hz)
    with_path = responses(system, grid)
    bare = responses(closed_loop(_bare(config, inertia_error)), grid)
    error = with_path[1, 0]
    ratio = with_path[0, 1] / bare[0, 1]
    return {"inertia_error": inertia_error, "stable": is_stable(system),
            "sensitivity_peak": float(np.max(np.abs(error[:-1]))),
            "disturbance_peak": float(np.max(np.abs(ratio[:-1]))),
            "disturbance_peak_hz": float(f[int(np.argmax(np.abs(ratio[:-1])))]),
            "removal_at_fd": float(1.0 - abs(ratio[-1]))}


def pdc_figures(config: PdcConfig, inertia_errors: Sequence[float] = INERTIA_ERRORS,
                points: int = GRID_POINTS) -> dict[str, Any]:
    """The PDC design's numbers: M_L, D_L, W, H·P_n at f_d, and Eq. 13's margin per inertia error."""
    design, model = config.pdc_design(), config.nominal()
    f = frequency_grid_hz(model.sample_time_s, points)
    pn = response(model.numerator, model.denominator, f, model.sample_time_s)
    hp = response(design.h, [1.0], f, model.sample_time_s) * pn
    margins = {}
    for eps in inertia_errors:
        b, a = inertia_perturbed(tf(model.numerator, model.denominator), eps)
        delta = response(b, a, f, model.sample_time_s) / pn - 1.0
        margins[eps] = float(np.max(np.abs(hp * delta)))
    return {"f_d_hz": design.f_d_hz, "magnitude_ml": design.magnitude_ml, "delay_samples": design.delay_samples,
            "w": list(design.w), "hp_gain_at_fd": abs(design.hp_at_fd),
            "hp_phase_deg_at_fd": bode_phase_deg(design.hp_at_fd), "hp_peak": float(np.max(np.abs(hp))),
            "eq13_margin": margins}


def design_report(configs: Mapping[str, PositionLoopConfig], f_d_hz: float,
                  inertia_errors: Sequence[float] = INERTIA_ERRORS,
                  points: int = GRID_POINTS) -> dict[str, dict[str, Any]]:
    """Per combination name: its loop figures per inertia error, and its PDC figures when it has a PDC."""
    report: dict[str, dict[str, Any]] = {}
    for name, config in configs.items():
        entry: dict[str, Any] = {"loops": [loop_figures(config, f_d_hz, eps, points) for eps in inertia_errors]}
        if isinstance(config, PdcConfig):
            entry["pdc"] = pdc_figures(config, inertia_errors, points)
        report[name] = entry
    return report


def pdc_frequency_responses(config: PdcConfig, points: int = GRID_POINTS) -> dict[str, np.ndarray]:
    """Figs. 7-8 of paper 002 as arrays: f [Hz] and the complex responses of P_n, P_m, L, W, H and H·P_n."""
    design, model = config.pdc_design(), config.nominal()
    t = model.sample_time_s
    f = frequency_grid_hz(t, points)
    pn = response(model.numerator, model.denominator, f, t)
    pm = design.magnitude_ml * np.exp(-2j * np.pi * f * t * design.delay_samples) * pn
    h = response(design.h, [1.0], f, t)
    return {"f_hz": f, "pn": pn, "pm": pm, "l": response(design.lowpass, [1.0], f, t),
            "w": response(design.w, [1.0], f, t), "h": h, "hp": h * pn}
