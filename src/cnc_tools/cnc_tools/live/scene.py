"""The 3D scene: the program's path and the tool's trail as foxglove ``SceneUpdate`` entities (frame ``machine``).

Positions in m, axes beyond the third dropped, missing ones 0 (a 2-axis run lies in z = 0).
"""
from __future__ import annotations

from collections import deque
from collections.abc import Sequence

import numpy as np
from foxglove.messages import (
    Color,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    SceneEntity,
    SceneUpdate,
    Timestamp,
)

from cnc_contour_control.motion.geometry import Program

FRAME_ID = "machine"
#: Points per program segment drawn (arcs need them; a line needs two).
POINTS_PER_SEGMENT = 64
#: Trail points kept (one per decimation window: 2000 × 20 ms = the last 40 s).
TRAIL_POINTS = 2000
#: Line widths, m.
PATH_WIDTH_M, TRAIL_WIDTH_M = 0.0002, 0.0003


def _point(position_m: Sequence[float]) -> Point3:
    xyz = [float(v) for v in position_m[:3]] + [0.0] * max(0, 3 - len(position_m))
    return Point3(x=xyz[0], y=xyz[1], z=xyz[2])


def program_points_m(program: Program) -> list[Sequence[float]]:
    """Points along the program's segments, m (lines: their ends; arcs: :data:`POINTS_PER_SEGMENT`)."""
    points: list[Sequence[float]] = []
    for segment in program.segments:
        count = 2 if not hasattr(segment, "center_m") else POINTS_PER_SEGMENT
        points.extend(np.atleast_2d(segment.point(np.linspace(0.0, segment.length_m, count))).tolist())
    return points


def _entity(entity_id: str, stamp_ns: int, points: list[Point3], color: Color, width_m: float) -> SceneEntity:
    stamp = Timestamp(sec=stamp_ns // 1_000_000_000, nsec=stamp_ns % 1_000_000_000)
    line = LinePrimitive(type=LinePrimitiveLineType.LineStrip, thickness=width_m, scale_invariant=False,
                         points=points, color=color)
    return SceneEntity(timestamp=stamp, frame_id=FRAME_ID, id=entity_id, lines=[line])


class Scene:
    """The program's path (set once) and the tool's trail (a point per window)."""

    def __init__(self) -> None:
        self.path: list[Point3] = []
        self.trail: deque[Point3] = deque(maxlen=TRAIL_POINTS)

    def set_program(self, program: Program) -> None:
        """Draw this program's path."""
        self.path = [_point(p) for p in program_points_m(program)]

    def add_tool(self, position_m: Sequence[float]) -> None:
        """One more trail point."""
        self.trail.append(_point(position_m))

    def update(self, stamp_ns: int) -> SceneUpdate:
        """Both entities as they stand (a late viewer gets the whole path with the next update)."""
        entities = [_entity("program", stamp_ns, self.path, Color(r=0.6, g=0.6, b=0.6, a=1.0), PATH_WIDTH_M)]
        if self.trail:
            entities.append(_entity("tool_trail", stamp_ns, list(self.trail), Color(r=0.1, g=0.5, b=1.0, a=1.0),
                                    TRAIL_WIDTH_M))
        return SceneUpdate(entities=entities)
