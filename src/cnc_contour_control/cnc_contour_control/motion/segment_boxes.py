"""Which segments of a long program can hold a point's nearest point: a prefilter without a loop (ROS-free).

:meth:`~cnc_contour_control.motion.geometry.Program.contour_distance` visits
segments one by one, skipping those whose bounding box lies farther than the
best distance found so far; over 200 000 segments that loop alone takes
seconds. :class:`SegmentBoxes` keeps every box and every segment end (a k-d
tree of the ends) as arrays, and for a batch of points ``p``

    U           = max_p min_k |v_k - p|      (v_k: segment starts and the program's end, points on the contour)
    candidates  = {s : gap(box_s, box of the batch) <= U}

A segment left out has a gap to every point above ``U``, which no point's
nearest distance exceeds: visiting only the candidates in program order gives
the same distances and indices (ties included). Consecutive ticks lie close
together, so a live batch keeps a handful of segments; a batch spread over
the whole program keeps them all (the plain scan).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cnc_contour_control.motion.points import FloatArray, IntArray


@dataclass(frozen=True)
class SegmentBoxes:
    """Bounding boxes ``low_m``, ``high_m`` (m, shape ``(S, n_axes)``) and ends ``vertex_m`` (``(S + 1, n_axes)``)."""

    low_m: FloatArray
    high_m: FloatArray
    vertex_m: FloatArray
    tree: Any = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        from scipy.spatial import cKDTree  # scipy only for a program this large: a node starts without it

        object.__setattr__(self, "tree", cKDTree(self.vertex_m))

    @classmethod
    def of(cls, segments: Sequence[Any]) -> SegmentBoxes:
        """The boxes and ends of ``segments`` (each with ``bounding_box_m()``, ``start_m``, ``end_m``)."""
        boxes = [segment.bounding_box_m() for segment in segments]
        vertices = [segment.start_m for segment in segments] + [segments[-1].end_m]
        return cls(np.array([b[0] for b in boxes], dtype=float), np.array([b[1] for b in boxes], dtype=float),
                   np.array(vertices, dtype=float))

    def candidates(self, points: FloatArray) -> IntArray:
        """Indices (ascending) of the segments that can hold the nearest point of some point (module notes).

        Points with a non-finite coordinate have no nearest point (the scan leaves them at infinity) and are left out.
        """
        finite = points[np.all(np.isfinite(points), axis=1)]
        if finite.shape[0] == 0:
            return np.zeros(0, dtype=np.intp)
        bound_m = float(np.max(self.tree.query(finite)[0]))
        low, high = finite.min(axis=0), finite.max(axis=0)
        gap = np.maximum(np.maximum(self.low_m - high, low - self.high_m), 0.0)
        return np.flatnonzero(np.einsum("sd,sd->s", gap, gap) <= bound_m * bound_m).astype(np.intp)
