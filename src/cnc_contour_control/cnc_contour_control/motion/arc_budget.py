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

Both bounds fall as ``v`` rises, so the budget at the top of a speed interval
holds over the whole interval: :func:`speed_bands` splits ``[0, V]`` at
``V sqrt(i / n)`` into ``n`` bands, each with the budget at its highest speed
(the planner accelerates through them in turn: a tangential acceleration that
grows as the speed drops, constant within a band, so every sample stays
closed-form). With ``f`` = 0.8 the time from rest to ``V`` is 1.53 times the
continuous budget's with one band, 1.06 with four, 1.026 with eight.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.points import FloatArray

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
    tangent = arc.max_abs_tangent() if max_abs_tangent is None else max_abs_tangent
    curvature = arc.max_abs_curvature_per_m() if max_abs_curvature_per_m is None else max_abs_curvature_per_m
    in_plane = np.zeros((1, arc.n_axes), dtype=bool)
    in_plane[0, list(arc.plane)] = True
    return float(combined_tangential_rows(
        np.array([arc.radius_m * (arc.sweep_rad / arc.length_m) ** 2]), np.array([arc.radius_m * arc.sweep_rad
                                                                                  / arc.length_m]),
        in_plane, np.array([speed_m_s]), np.asarray(max_acceleration_m_s2, dtype=float),
        np.asarray(tangent, dtype=float)[None, :], np.asarray(curvature, dtype=float)[None, :])[0])


def combined_tangential_rows(kappa_per_m: FloatArray, rate: FloatArray, in_plane: NDArray[np.bool_],
                             speed_m_s: FloatArray, max_acceleration_m_s2: FloatArray, max_abs_tangent: FloatArray,
                             max_abs_curvature_per_m: FloatArray) -> FloatArray:
    """:func:`combined_tangential_m_s2` of many arcs at once (the planner's path).

    Parameters
    ----------
    kappa_per_m, rate : ndarray, shape (M,)
        Each arc's curvature ``R (sweep / length)**2`` (1/m) and ``ρ = R sweep / length``.
    in_plane : ndarray of bool, shape (M, n_axes)
        True on each arc's two plane axes.
    speed_m_s : ndarray, shape (M,)
        Largest path speed on each arc, m/s.
    max_acceleration_m_s2 : ndarray, shape (n_axes,)
        Per-axis acceleration limits, m/s².
    max_abs_tangent, max_abs_curvature_per_m : ndarray, shape (M, n_axes)
        Each arc's largest ``|T_j|`` and ``|K_j|`` (1/m).

    Returns
    -------
    ndarray, shape (M,)
        Tangential acceleration, m/s² (inf where no axis bounds it).
    """
    limit = np.asarray(max_acceleration_m_s2, dtype=float)[None, :]
    centripetal_sq = (np.asarray(speed_m_s, dtype=float) ** 2)[:, None]
    split = (limit - centripetal_sq * max_abs_curvature_per_m) / np.maximum(max_abs_tangent, _MIN_TANGENT)
    combined = np.sqrt(np.maximum(limit * limit - (centripetal_sq * kappa_per_m[:, None]) ** 2, 0.0)) / rate[:, None]
    used = max_abs_tangent > _MIN_TANGENT
    out_of_plane = np.divide(limit, max_abs_tangent, out=np.full(used.shape, np.inf), where=used)
    bounds = np.where(in_plane, np.maximum(np.maximum(split, combined), 0.0), out_of_plane)
    return bounds.min(axis=1)


def band_edges_m_s(cruise_m_s: FloatArray, n_bands: int) -> FloatArray:
    """Speed band edges ``V sqrt(i / n)``, i = 0..n, of every row, m/s, shape ``(M, n_bands + 1)``."""
    return np.asarray(cruise_m_s, dtype=float)[:, None] * np.sqrt(np.arange(n_bands + 1) / n_bands)[None, :]


def speed_bands(kappa_per_m: FloatArray, rate: FloatArray, in_plane: NDArray[np.bool_], cruise_m_s: FloatArray,
                max_acceleration_m_s2: FloatArray, max_abs_tangent: FloatArray,
                max_abs_curvature_per_m: FloatArray, n_bands: int) -> tuple[FloatArray, FloatArray]:
    """Speed bands of many arcs and the tangential acceleration that holds over each (the budget at its top).

    Parameters are those of :func:`combined_tangential_rows` (``cruise_m_s``: each arc's cruise speed), and
    ``n_bands`` (>= 1) the number of bands.

    Returns
    -------
    edges_m_s : ndarray, shape (M, n_bands + 1)
        Band edges from 0 to the cruise speed, m/s (:func:`band_edges_m_s`).
    accel_m_s2 : ndarray, shape (M, n_bands)
        Tangential acceleration in each band, m/s²; the last band's is :func:`combined_tangential_rows` at the
        cruise speed, the others are larger or equal.
    """
    edges = band_edges_m_s(cruise_m_s, n_bands)
    rows = np.repeat(np.arange(edges.shape[0]), n_bands)
    accel = combined_tangential_rows(kappa_per_m[rows], rate[rows], in_plane[rows], edges[:, 1:].ravel(),
                                     max_acceleration_m_s2, max_abs_tangent[rows], max_abs_curvature_per_m[rows])
    return edges, accel.reshape(edges.shape[0], n_bands)
