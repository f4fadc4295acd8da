"""The linear position loop with paper 002's disturbance paths, built with python-control (ROS-free).

Signals (velocities and commands in counts/s, position in counts)::

    y  = P (v + d)                 plant: velocity command v plus input disturbance d -> velocity
    x  = T(1 + z⁻¹)/(2(1 − z⁻¹)) y position by the trapezoid rule, as the ``paper002`` plant integrates it
                                   (P's own z⁻¹ is the one-sample command delay)
    e  = r − x,  u = k_p e         P position loop (the paper's cascade)
    T_E = H (y − P_n v)            PDC (inner), when used
    d̂  = [Q P_n⁻¹] y − Q (v + T_E) DOB (outer), when used
    c  = M (P_n u − y)             MBDA (outer), when used
    v  = u − d̂ − T_E + c

:func:`closed_loop` interconnects the blocks (:func:`control.interconnect`,
no minimisation), so its poles are the loop's internal modes: :func:`is_stable`
is internal stability. The perturbed plant of an inertia error ε is
P = P_n / ((1 + ε)(1 − P_n) + P_n): the velocity loop's open gain
P_n/(1 − P_n) divided by (1 + ε).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import control
import numpy as np

Tf = tuple[np.ndarray, np.ndarray]  # (numerator, denominator) in ascending powers of z⁻¹


def tf(numerator: Sequence[float], denominator: Sequence[float] = (1.0,)) -> Tf:
    """A block from z⁻¹ coefficients (ascending powers)."""
    return np.asarray(numerator, dtype=float), np.asarray(denominator, dtype=float)


@dataclass(frozen=True)
class LoopBlocks:
    """The blocks of one combination (``None``: the path is absent).

    Attributes
    ----------
    plant, model : Tf
        P (true) and P_n (nominal).
    kp_per_s : float
        Position gain [1/s].
    sample_time_s : float
        T [s].
    h, q, q_inverse_model, m : Tf or None
        PDC's H, DOB's Q and Q·P_n⁻¹, MBDA's M.
    """

    plant: Tf
    model: Tf
    kp_per_s: float
    sample_time_s: float
    h: Tf | None = None
    q: Tf | None = None
    q_inverse_model: Tf | None = None
    m: Tf | None = None


def _system(block: Tf, dt: float, inputs: str, outputs: str, name: str) -> control.TransferFunction:
    """b(z⁻¹)/a(z⁻¹) as a python-control system in z (both padded to one length)."""
    b, a = block
    n = max(len(a), len(b))
    return control.tf(np.pad(b, (0, n - len(b))), np.pad(a, (0, n - len(a))), dt,
                      inputs=inputs, outputs=outputs, name=name)


def _paths(blocks: LoopBlocks) -> tuple[list[control.TransferFunction], list[str]]:
    """The optional paths' systems and the terms they add to v."""
    dt, systems, terms = blocks.sample_time_s, [], []
    if blocks.h is not None:
        systems += [_system(blocks.model, dt, "v", "yn_v", "model_v"),
                    control.summing_junction(["y", "-yn_v"], "res", name="pdc_residual"),
                    _system(blocks.h, dt, "res", "te", "h")]
        terms.append("-te")
    if blocks.q is not None:
        # LoopBlocks gives q_inverse_model whenever it gives q
        systems += [_system(blocks.q_inverse_model, dt, "y", "qy", "q_inverse"),  # type: ignore[arg-type]  # see above
                    control.summing_junction(["v", "te"] if blocks.h is not None else ["v"], "uin", name="uin"),
                    _system(blocks.q, dt, "uin", "qu", "q"),
                    control.summing_junction(["qy", "-qu"], "dh", name="dob")]
        terms.append("-dh")
    if blocks.m is not None:
        systems += [_system(blocks.model, dt, "u", "yn_u", "model_u"),
                    control.summing_junction(["yn_u", "-y"], "mres", name="mbda_residual"),
                    _system(blocks.m, dt, "mres", "c", "m")]
        terms.append("c")
    return systems, terms


def closed_loop(blocks: LoopBlocks) -> control.InputOutputSystem:
    """The loop from (r, d) to (x, e) as one discrete state-space system (all internal modes kept)."""
    dt = blocks.sample_time_s
    systems, terms = _paths(blocks)
    systems += [control.summing_junction(["v", "d"], "pin", name="plant_input"),
                _system(blocks.plant, dt, "pin", "y", "plant"),
                _system(tf([0.5 * dt, 0.5 * dt], [1.0, -1.0]), dt, "y", "x", "integrator"),
                control.summing_junction(["r", "-x"], "e", name="error"),
                control.tf([blocks.kp_per_s], [1.0], dt, inputs="e", outputs="u", name="kp"),
                control.summing_junction(["u", *terms], "v", name="command")]
    return control.interconnect(systems, inplist=["r", "d"], outlist=["x", "e"], check_unused=False)


def is_stable(system: control.InputOutputSystem, margin: float = 1e-9) -> bool:
    """True when every pole lies strictly inside the unit circle."""
    return bool(np.all(np.abs(system.poles()) < 1.0 - margin))


def responses(system: control.InputOutputSystem, f_hz: np.ndarray) -> np.ndarray:
    """Complex responses at ``f_hz`` [Hz], shape (outputs (x, e), inputs (r, d), len(f_hz))."""
    omega = 2.0 * np.pi * np.asarray(f_hz, dtype=float)
    return np.asarray(system(np.exp(1j * omega * system.dt)))


def inertia_perturbed(model: Tf, inertia_error: float) -> Tf:
    """P for an inertia (1 + ε)·J: P_n / ((1 + ε)(1 − P_n) + P_n), as polynomials in z⁻¹."""
    b, a = model
    n = max(len(a), len(b))
    b, a = np.pad(b, (0, n - len(b))), np.pad(a, (0, n - len(a)))
    return b.copy(), (1.0 + inertia_error) * (a - b) + b


#: Frequency grid points between 0 and Nyquist (both excluded).
GRID_POINTS = 2000


def frequency_grid_hz(sample_time_s: float, points: int = GRID_POINTS) -> np.ndarray:
    """Frequencies (0, Nyquist) exclusive [Hz], ``points`` of them."""
    nyquist = 0.5 / sample_time_s
    return np.linspace(nyquist / points, nyquist * (1.0 - 1.0 / points), points)
