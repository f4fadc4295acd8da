"""From a recorded run to the circle trace a ballbar would measure (ROS-free).

The run's program must be one circle (:func:`cnc_tools.analysis.circular.circle_of`);
its direction is the arcs' (``clockwise`` flag), its feed the arcs' programmed
feed (length-weighted). The trace is the measured position in the arc plane
(:func:`measured_positions`) at the stamps that both it and ``reference`` hold,
where the reference is on one of the circle's arcs and not yet ``done`` (the
settle after the end of the program is left out). ``cnc-contour circular`` (a
bag) and the tuner's simulated circular test (an engine run) both use it.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.motion.geometry import ArcSegment
from cnc_tools.analysis.ballbar import CircleTrace
from cnc_tools.analysis.circular import Circle, circle_of
from cnc_tools.run_record import RunRecord

#: How the samples of a trace are chosen (printed and written to the JSON).
SAMPLE_RULE = ("measured positions (tool_position when recorded, else joint_states) at the stamps they and "
               "reference share, while the reference is on the circle's arc and not done (settle after the "
               "program left out)")


@dataclass(frozen=True, eq=False)
class BagTrace:
    """One run's circle trace and where it came from (a bag's path, or a label for an engine run)."""

    bag: Path
    circle: Circle
    trace: CircleTrace
    n_samples: int


def _direction(bag: Path, arcs: Sequence[ArcSegment]) -> str:
    directions = {"cw" if arc.clockwise else "ccw" for arc in arcs}
    if len(directions) != 1:
        raise CncError(f"{bag}: the program's arcs must all run one way, got {sorted(directions)}")
    return directions.pop()


def measured_positions(record: RunRecord) -> tuple[np.ndarray, np.ndarray]:
    """Stamps (N,) [ns] and positions (N, n_axes) [m] a ballbar would measure: the tool position when the run
    recorded one (a plant with machine faults), else the joint states (motor side)."""
    series = record.tool_position if record.tool_position is not None else record.joint_states
    return series.stamp_ns, series.position_m


def arc_samples(record: RunRecord, circle: Circle) -> np.ndarray:
    """Measured plane positions (M, 2), m, on the circle's arc (see :data:`SAMPLE_RULE`)."""
    reference = record.reference
    if reference is None:
        raise CncError("the bag holds no reference, so the samples on the circle cannot be told apart")
    stamp_ns, position_m = measured_positions(record)
    _, js_rows, ref_rows = np.intersect1d(stamp_ns, reference.stamp_ns, return_indices=True)
    on_arc = ~reference.done[ref_rows] & (reference.segment_index[ref_rows] < len(record.program.segments))
    points = position_m[js_rows[on_arc]][:, list(circle.plane)]
    return points[np.isfinite(points).all(axis=1)]


def trace_of(bag: Path, record: RunRecord) -> BagTrace:
    """The circle trace of one recorded run; CncError names the bag and the problem."""
    if not record.integrity.complete:
        raise CncError(f"{bag}: bag is damaged: {record.integrity.describe()}")
    circle = circle_of(record.program)
    if circle is None:
        raise CncError(f"{bag}: the program is not one circle (every segment must be an arc of one centre, "
                       f"radius and plane), got {len(record.program.segments)} segments")
    arcs = [seg for seg in record.program.segments if isinstance(seg, ArcSegment)]
    length_m = sum(arc.length_m for arc in arcs)
    feed_m_s = sum(arc.feed_m_s * arc.length_m for arc in arcs) / length_m
    try:
        points = arc_samples(record, circle)
        trace = CircleTrace(points, circle.center_m, circle.radius_m, _direction(bag, arcs), feed_m_s)
    except CncError as err:
        raise CncError(f"{bag}: {err}") from err
    return BagTrace(bag, circle, trace, int(points.shape[0]))
