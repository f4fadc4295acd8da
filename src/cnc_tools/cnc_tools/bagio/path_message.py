"""A recorded ``cnc_contour_interfaces/msg/Path`` message back to the program's geometry (no rclpy).

The interpolator publishes the program it runs on the path topic (transient local); a bag keeps it, and
scoring, replays and live views rebuild the :class:`~cnc_contour_control.motion.geometry.Program` from it.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from cnc_contour_control.core.errors import BagError
from cnc_contour_control.motion.geometry import ArcSegment, LineSegment, Program


def _line(seg: Any, clockwise: bool) -> LineSegment:
    return LineSegment(start_m=np.asarray(seg.start_m, np.float64), end_m=np.asarray(seg.end_m, np.float64),
                       feed_m_s=float(seg.feed_m_s))


def _arc(seg: Any, clockwise: bool) -> ArcSegment:
    return ArcSegment(start_m=np.asarray(seg.start_m, np.float64), end_m=np.asarray(seg.end_m, np.float64),
                      center_m=np.asarray(seg.center_m, np.float64), clockwise=clockwise,
                      plane=tuple(int(i) for i in seg.plane_axes),  # type: ignore[arg-type]  # ArcSegment checks: 2 axes
                      feed_m_s=float(seg.feed_m_s))


#: PathSegment.kind -> (builder, clockwise).
_SEGMENT_KINDS: dict[int, tuple[Callable[[object, bool], LineSegment | ArcSegment], bool]] = {
    0: (_line, False), 1: (_arc, True), 2: (_arc, False),
}


def program_from_path(message: Any) -> Program:
    """Build the program geometry from a deserialised ``cnc_contour_interfaces/msg/Path``.

    Its ``path_tolerance_m`` is the message's; None when the message says NaN (not known) or was recorded
    with a ``Path`` definition that lacks the field (the bag's own schema, before the field existed).
    """
    segments = []
    for index, seg in enumerate(message.segments):
        if seg.kind not in _SEGMENT_KINDS:
            raise BagError(f"path segment {index}: kind {seg.kind} is not one of {sorted(_SEGMENT_KINDS)}")
        build, clockwise = _SEGMENT_KINDS[seg.kind]
        segments.append(build(seg, clockwise))
    tolerance_m = float(getattr(message, "path_tolerance_m", math.nan))
    return Program(name=message.program_name, axis_names=tuple(message.axis_names),
                   segments=tuple(segments), path_tolerance_m=None if math.isnan(tolerance_m) else tolerance_m)
