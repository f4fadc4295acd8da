"""Corner blends: one :class:`Blend` per rounded corner, and all of a program's blends as arrays (:class:`BlendTable`).

The planner works on the table (one NumPy row per blend, built without a
Python object per corner); :attr:`cnc_contour_control.motion.blending.BlendedProgram.blends`
gives the same blends as :class:`Blend` objects when asked.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.points import FloatArray, IntArray


@dataclass(frozen=True)
class Blend:
    """One rounded corner: at the junction before programmed segment ``junction``.

    ``radius_m`` is the arc radius (m), ``trim_m`` the length taken from the
    segment before (m), ``trim_after_m`` the one taken from the segment after
    (m; equal for line-line corners), ``deviation_m`` the arc's largest
    distance from the programmed path (m, <= the tolerance; for line-line
    corners the bound ``e``). ``start_m``, ``end_m`` and ``center_m`` (shape
    ``(n_axes,)``, m) are the arc's tangent points and centre, ``plane`` its
    plane and ``clockwise`` its direction. A blend of several pieces (a 3-axis
    line-arc corner, :mod:`cnc_contour_control.motion.blend_ramp`) has them in
    ``pieces``, from ``start_m`` to ``end_m`` (the centre, plane and direction
    are the last piece's); a one-arc blend has none.
    """

    junction: int
    radius_m: float
    trim_m: float
    deviation_m: float
    trim_after_m: float = math.nan
    start_m: FloatArray | None = field(default=None, repr=False)
    end_m: FloatArray | None = field(default=None, repr=False)
    center_m: FloatArray | None = field(default=None, repr=False)
    plane: tuple[int, int] = (0, 1)
    clockwise: bool = False
    pieces: tuple[ArcSegment, ...] = field(default=(), repr=False)


@dataclass(frozen=True)
class BlendTable:
    """``M`` blends as arrays, in junction order: the fields of :class:`Blend`, one row each.

    ``junction`` ``(M,)`` int; ``radius_m``, ``trim_m``, ``deviation_m``, ``trim_after_m`` ``(M,)``, m;
    ``start_m``, ``end_m``, ``center_m`` ``(M, n_axes)``, m; ``plane`` ``(M, 2)`` int; ``clockwise`` ``(M,)`` bool;
    ``pieces`` ``(M,)`` object: a blend's tuple of pieces, or None for a one-arc blend.
    """

    junction: IntArray
    radius_m: FloatArray
    trim_m: FloatArray
    deviation_m: FloatArray
    trim_after_m: FloatArray
    start_m: FloatArray
    end_m: FloatArray
    center_m: FloatArray
    plane: IntArray
    clockwise: NDArray[np.bool_]
    pieces: NDArray[np.object_]

    def __len__(self) -> int:
        return int(self.junction.size)

    @classmethod
    def empty(cls, n_axes: int) -> BlendTable:
        """No blend."""
        return cls.from_blends((), n_axes)

    @classmethod
    def from_blends(cls, blends: Sequence[Blend], n_axes: int) -> BlendTable:
        """The table of ``blends`` (in the order given)."""
        def column(name: str, dtype: type) -> np.ndarray:
            return np.array([getattr(blend, name) for blend in blends], dtype=dtype)

        def points(name: str) -> FloatArray:
            return column(name, float).reshape(len(blends), n_axes)

        pieces = one_arc(len(blends))
        for i, blend in enumerate(blends):
            pieces[i] = blend.pieces or None
        return cls(column("junction", np.intp), column("radius_m", float), column("trim_m", float),
                   column("deviation_m", float), column("trim_after_m", float), points("start_m"), points("end_m"),
                   points("center_m"), column("plane", np.intp).reshape(len(blends), 2), column("clockwise", bool),
                   pieces)

    def merged(self, other: BlendTable) -> BlendTable:
        """Both tables' rows in junction order."""
        names = [f.name for f in self.__dataclass_fields__.values()]
        joined = {name: np.concatenate([getattr(self, name), getattr(other, name)]) for name in names}
        order = np.argsort(joined["junction"], kind="stable")
        return BlendTable(**{name: values[order] for name, values in joined.items()})

    def subset(self, keep: NDArray[np.bool_]) -> BlendTable:
        """The rows where ``keep`` (``(M,)`` bool) is True, in order."""
        names = [f.name for f in self.__dataclass_fields__.values()]
        return BlendTable(**{name: getattr(self, name)[keep] for name in names})

    @property
    def has_pieces(self) -> NDArray[np.bool_]:
        """Whether each blend is of several pieces, ``(M,)``."""
        return np.array([p is not None for p in self.pieces], dtype=bool)

    def rows(self) -> tuple[Blend, ...]:
        """One :class:`Blend` per row."""
        columns = zip(self.junction.tolist(), self.radius_m.tolist(), self.trim_m.tolist(), self.deviation_m.tolist(),
                      self.trim_after_m.tolist(), self.plane.tolist(), self.clockwise.tolist())
        return tuple(Blend(k, r, trim, deviation, after, self.start_m[i], self.end_m[i], self.center_m[i], (a, b), cw,
                           self.pieces[i] or ())
                     for i, (k, r, trim, deviation, after, (a, b), cw) in enumerate(columns))


def one_arc(count: int) -> NDArray[np.object_]:
    """The ``pieces`` column of ``count`` one-arc blends (all None)."""
    return np.full(count, None, dtype=object)
