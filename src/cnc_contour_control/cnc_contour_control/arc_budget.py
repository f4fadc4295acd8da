"""An arc's tangential acceleration when tangential and centripetal parts share each axis's budget.

On an arc of curvature ``κ`` (helix: the exact helix curvature) the
acceleration of an in-plane axis ``j`` at angle ``θ`` is

    a_j = a_t T_j + v² K_j,   T_j = ∓ρ sin θ (or cos θ),   K_j = -κ cos θ (or sin θ)

with ``ρ = R sweep / length <= 1``. ``(T_j / ρ, K_j / κ)`` is a unit vector, so
(Cauchy-Schwarz) ``|a_j| <= sqrt((a_t ρ)² + (v² κ)²)`` at every ``θ``: the
tangential acceleration may be ``sqrt(amax_j² - (v² κ)²) / ρ`` at speeds up to
``v``. The split budget (``|a_t| |T_j|max + v² |K_j|max <= amax_j``) is the
other valid bound; each axis takes the larger of the two. An out-of-plane
(helix) axis has ``K_j = 0`` and ``|a_t| |T_j| <= amax_j``. The planner keeps
the speed on a segment at most its cruise speed, which is the ``v`` used here.
"""
from __future__ import annotations

import math

import numpy as np

from cnc_contour_control.arc import ArcSegment
from cnc_contour_control.points import FloatArray

_MIN_TANGENT = 1.0e-12


def combined_tangential_m_s2(arc: ArcSegment, speed_m_s: float, max_acceleration_m_s2: FloatArray,
                             max_abs_tangent: FloatArray | None = None,
                             max_abs_curvature_per_m: FloatArray | None = None) -> float:
    """Largest tangential acceleration (m/s², >= 0) on ``arc`` at speeds up to ``speed_m_s`` (m/s).

    Parameters
    ----------
    arc : ArcSegment
        The arc (planar or helical).
    speed_m_s : float
        Largest path speed on the arc, m/s.
    max_acceleration_m_s2 : ndarray, shape (n_axes,)
        Per-axis acceleration limits, m/s².
    max_abs_tangent, max_abs_curvature_per_m : ndarray, shape (n_axes,), optional
        The arc's :meth:`~ArcSegment.max_abs_tangent` and :meth:`~ArcSegment.max_abs_curvature_per_m`
        (1/m) if the caller has them.
    """
    kappa = arc.radius_m * (arc.sweep_rad / arc.length_m) ** 2
    rate = arc.radius_m * arc.sweep_rad / arc.length_m
    tangent = arc.max_abs_tangent() if max_abs_tangent is None else max_abs_tangent
    curvature = arc.max_abs_curvature_per_m() if max_abs_curvature_per_m is None else max_abs_curvature_per_m
    centripetal_sq = speed_m_s ** 2
    bounds = []
    for j, limit in enumerate(np.asarray(max_acceleration_m_s2, dtype=float).tolist()):
        if j in arc.plane:
            split = (limit - centripetal_sq * curvature[j]) / max(tangent[j], _MIN_TANGENT)
            combined = math.sqrt(max(limit * limit - (centripetal_sq * kappa) ** 2, 0.0)) / rate
            bounds.append(max(split, combined, 0.0))
        elif tangent[j] > _MIN_TANGENT:
            bounds.append(limit / tangent[j])
    return min(bounds) if bounds else math.inf
