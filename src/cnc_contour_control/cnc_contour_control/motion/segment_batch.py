"""Many line and arc segments built at once from arrays: the checks and derived fields of their constructors in NumPy.

:class:`~cnc_contour_control.motion.geometry.LineSegment` and
:class:`~cnc_contour_control.motion.arc.ArcSegment` check and derive their fields one
segment at a time (tens of µs each); a planner that builds hundreds of
thousands of segments (trimmed lines and blend arcs) does the same arithmetic
here over arrays and hands each segment its fields through ``from_validated``.
A row that fails a check is built by the class itself, which raises its own
error (or, at a rounding edge, builds it); so the results and the errors are
the constructors' (``test_segment_batch.py`` compares them field by field).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.geometry import LineSegment
from cnc_contour_control.motion.points import (
    MIN_LENGTH_M,
    POSITION_TOLERANCE_M,
    RADIUS_TOLERANCE_M,
    TWO_PI,
    FloatArray,
)


def _read_only(*arrays: FloatArray) -> None:
    for array in arrays:
        array.setflags(write=False)




def _rows_norm(vectors: FloatArray) -> FloatArray:
    return np.sqrt(np.einsum("ij,ij->i", vectors, vectors))


def line_segments(start_m: FloatArray, end_m: FloatArray, feed_m_s: FloatArray,
                  source_line: Sequence[int | None]) -> list[LineSegment]:
    """``LineSegment(start_m[i], end_m[i], feed_m_s[i], source_line[i])`` for every row ``i``.

    Parameters
    ----------
    start_m, end_m : ndarray, shape (N, n_axes)
        End points, m.
    feed_m_s : ndarray, shape (N,)
        Feeds, m/s.
    source_line : sequence of int or None, length N
        G-code lines.
    """
    start, end = np.array(start_m, dtype=float), np.array(end_m, dtype=float)
    feed = np.asarray(feed_m_s, dtype=float)
    delta = end - start
    length = _rows_norm(delta)
    ok = np.isfinite(start).all(axis=1) & np.isfinite(end).all(axis=1) & (length >= MIN_LENGTH_M)
    unit = delta / np.where(ok, length, 1.0)[:, None]
    _read_only(start, end, unit)
    build = LineSegment.from_validated
    out = [build(p0, p1, f, line, n, u) for p0, p1, f, line, n, u in
           zip(start, end, feed.tolist(), source_line, length.tolist(), unit)]
    for i in np.flatnonzero(~(ok & np.isfinite(feed) & (feed > 0.0))).tolist():
        out[i] = LineSegment(start[i], end[i], float(feed[i]), source_line[i])  # raises its own error
    return out


def _arc_angles(start: FloatArray, end: FloatArray, center: FloatArray, plane: NDArray[np.intp],
                clockwise: NDArray[np.bool_]) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
    """Radius (m), start angle (rad), sweep (rad, in (0, 2π]) and validity of every arc (``arc._arc_angles``)."""
    rows, a, b = np.arange(len(start)), plane[:, 0], plane[:, 1]
    start_a, start_b = start[rows, a] - center[rows, a], start[rows, b] - center[rows, b]
    end_a, end_b = end[rows, a] - center[rows, a], end[rows, b] - center[rows, b]
    radius, end_radius = np.hypot(start_a, start_b), np.hypot(end_a, end_b)
    ok = (radius >= MIN_LENGTH_M) & (np.abs(end_radius - radius) <= RADIUS_TOLERANCE_M)
    start_angle = np.arctan2(start_b, start_a)
    difference = np.arctan2(end_b, end_a) - start_angle
    sweep = np.mod(np.where(clockwise, -difference, difference), TWO_PI)
    full = np.hypot(end[rows, a] - start[rows, a], end[rows, b] - start[rows, b]) <= POSITION_TOLERANCE_M
    sweep = np.where(full | ~(sweep > 0.0), TWO_PI, sweep)
    return radius, start_angle, sweep, ok


def arc_segments(start_m: FloatArray, end_m: FloatArray, center_m: FloatArray, clockwise: NDArray[np.bool_],
                 plane: NDArray[np.intp], feed_m_s: FloatArray,
                 source_line: Sequence[int | None]) -> list[ArcSegment]:
    """``ArcSegment(start_m[i], end_m[i], center_m[i], clockwise[i], plane[i], feed_m_s[i], source_line[i])`` per row.

    Parameters
    ----------
    start_m, end_m, center_m : ndarray, shape (N, n_axes)
        Start, end and centre, m.
    clockwise : ndarray of bool, shape (N,)
        Directions.
    plane : ndarray of int, shape (N, 2)
        Each arc's two plane axes.
    feed_m_s : ndarray, shape (N,)
        Feeds, m/s.
    source_line : sequence of int or None, length N
        G-code lines.
    """
    start, end, center = (np.array(v, dtype=float) for v in (start_m, end_m, center_m))
    planes = np.asarray(plane, dtype=np.intp).reshape(len(start), 2)
    turn, feed = np.asarray(clockwise, dtype=bool), np.asarray(feed_m_s, dtype=float)
    n_axes = start.shape[1]
    finite = np.isfinite(start).all(axis=1) & np.isfinite(end).all(axis=1) & np.isfinite(center).all(axis=1)
    planes_ok = (planes[:, 0] != planes[:, 1]) & (planes >= 0).all(axis=1) & (planes < n_axes).all(axis=1)
    safe = np.where(planes_ok[:, None], planes, [0, 1])
    radius, start_angle, sweep, ok = _arc_angles(start, end, center, safe, turn)
    rise = end - start
    rows = np.arange(len(start))
    rise[rows, safe[:, 0]] = rise[rows, safe[:, 1]] = 0.0
    length = np.hypot(radius * sweep, _rows_norm(rise))
    _read_only(start, end, center, rise)
    columns = zip(start, end, center, turn.tolist(), map(tuple, planes.tolist()), feed.tolist(), source_line,
                  radius.tolist(), sweep.tolist(), start_angle.tolist(), length.tolist(), rise)
    build = ArcSegment.from_validated
    out = [build({"start_m": p0, "end_m": p1, "center_m": c, "clockwise": cw, "plane": p, "feed_m_s": f,
                  "source_line": line, "radius_m": r, "sweep_rad": w, "start_angle_rad": a0, "length_m": n,
                  "rise_m": h}) for p0, p1, c, cw, p, f, line, r, w, a0, n, h in columns]
    for i in np.flatnonzero(~(finite & planes_ok & ok & np.isfinite(feed) & (feed > 0.0))).tolist():
        out[i] = ArcSegment(start[i], end[i], center[i], bool(turn[i]), tuple(planes[i]), float(feed[i]),
                            source_line[i])  # raises its own error
    return out
