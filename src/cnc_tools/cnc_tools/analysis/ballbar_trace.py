"""From a recorded run to the circle trace a ballbar would measure (ROS-free).

The run's program must be one circle (:func:`cnc_tools.analysis.circular.circle_of`);
its direction is the arcs' (``clockwise`` flag), its feed the arcs' programmed
feed (length-weighted). The trace is the measured position in the arc plane
(:func:`measured_positions`) at the stamps that both it and ``reference`` hold.

Which of them, as a ballbar test takes them (ISO 230-4's circular test, the
ballbar practice): the program runs a **feed-in arc**, the measured 360° turn
and a **feed-out arc** on the same circle, and only the turn is measured, so
the start from rest (the servo's transient, the acceleration) and the stop
fall outside it. The measured turn is the 360° in the middle of the
programmed arc (reference path length from ``(L − 2πR)/2`` to ``(L + 2πR)/2``,
``L`` the program's arc length): feed-in and feed-out arcs of ``(L − 2πR)/2``
each, which must be at least :data:`MIN_FEED_ARC_DEG`. A program shorter than
that (one turn from rest) is diagnosed over the whole program while the
reference is not ``done``, and the trace says so (:data:`WHOLE_PROGRAM_RULE`):
its start and end transients are then read as if they were the machine.
``cnc-contour circular`` (a bag) and the tuner's simulated circular test (an
engine run) both use it.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.motion.geometry import ArcSegment
from cnc_tools.analysis.ballbar import CircleTrace
from cnc_tools.analysis.circular import Circle, circle_of
from cnc_tools.run_record import RunRecord

#: Shortest feed-in (and feed-out) arc around the measured turn, degrees.
MIN_FEED_ARC_DEG = 90.0
_POSITIONS = ("measured positions (tool_position when recorded, else joint_states) at the stamps they and "
              "reference share")
#: How the samples of a standard trace are chosen (printed and written to the JSON).
SAMPLE_RULE = (f"{_POSITIONS}, on the measured 360° turn only: the middle 360° of the programmed arc, "
               f"after a feed-in arc and before a feed-out arc of >= {MIN_FEED_ARC_DEG:g}° each")
#: How they are chosen when the program has no such feed-in and feed-out arcs.
WHOLE_PROGRAM_RULE = (f"{_POSITIONS}, over the whole program while the reference is not done: NOT a standard "
                      f"test (no feed-in/feed-out arcs of >= {MIN_FEED_ARC_DEG:g}°), the start and end transients "
                      "are in every figure")


@dataclass(frozen=True, eq=False)
class BagTrace:
    """One run's circle trace and where it came from (a bag's path, or a label for an engine run)."""

    bag: Path
    circle: Circle
    trace: CircleTrace
    n_samples: int
    feed_in_deg: float = 0.0
    rule: str = SAMPLE_RULE

    @property
    def standard(self) -> bool:
        """True when the samples are a measured turn between feed-in and feed-out arcs."""
        return self.rule == SAMPLE_RULE


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


def feed_in_deg(record: RunRecord, circle: Circle) -> float | None:
    """The feed-in (= feed-out) arc before the measured turn, degrees; None when shorter than the minimum."""
    arc_m = sum(seg.length_m for seg in record.program.segments)
    lead_m = 0.5 * (arc_m - 2.0 * math.pi * circle.radius_m)
    lead_deg = math.degrees(lead_m / circle.radius_m)
    return lead_deg if lead_deg >= MIN_FEED_ARC_DEG - 1e-9 else None


def arc_samples(record: RunRecord, circle: Circle, lead_deg: float | None = None) -> np.ndarray:
    """Measured plane positions (M, 2), m: the measured turn after ``lead_deg`` of feed-in arc, or the whole
    program while the reference is not done when ``lead_deg`` is None (see the module docstring)."""
    reference = record.reference
    if reference is None:
        raise CncError("the bag holds no reference, so the samples on the circle cannot be told apart")
    stamp_ns, position_m = measured_positions(record)
    _, js_rows, ref_rows = np.intersect1d(stamp_ns, reference.stamp_ns, return_indices=True)
    keep = ~reference.done[ref_rows] & (reference.segment_index[ref_rows] < len(record.program.segments))
    if lead_deg is not None:
        start_m = math.radians(lead_deg) * circle.radius_m
        travelled_m = reference.path_length_m[ref_rows] - start_m
        keep &= (travelled_m >= 0.0) & (travelled_m < 2.0 * math.pi * circle.radius_m)
    points = position_m[js_rows[keep]][:, list(circle.plane)]
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
    lead_deg = feed_in_deg(record, circle)
    try:
        points = arc_samples(record, circle, lead_deg)
        trace = CircleTrace(points, circle.center_m, circle.radius_m, _direction(bag, arcs), feed_m_s)
    except CncError as err:
        raise CncError(f"{bag}: {err}") from err
    rule = WHOLE_PROGRAM_RULE if lead_deg is None else SAMPLE_RULE
    return BagTrace(bag, circle, trace, int(points.shape[0]), lead_deg or 0.0, rule)
