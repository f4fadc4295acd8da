"""The planned program's segments from the programmed ones and their blends, built over arrays.

For every programmed segment ``k`` the planned program has, in order, the blend
arc of the corner before it (if any) and the segment itself, trimmed to the
blends at its two ends. A trimmed line shorter than ``MIN_LENGTH_M`` (or
reversed by rounding, when two blends take half of it each) is dropped; the next
blend arc then starts where the planned path is (the previous planned
segment's end), so the path stays contiguous. An untouched segment is the
programmed object itself. Trimmed lines and arcs and the blend arcs are built
all at once (:mod:`cnc_contour_control.motion.segment_batch`): one NumPy pass per kind
instead of one constructor call per segment. A blend of several pieces (a 3-axis line-arc corner) brings
its pieces as they are.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import cast

import numpy as np

from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.blend_table import BlendTable
from cnc_contour_control.motion.geometry import LineSegment, Program, Segment
from cnc_contour_control.motion.points import MIN_LENGTH_M, FloatArray
from cnc_contour_control.motion.segment_batch import arc_segments, line_segments


def _pieces(program: Program, blends: BlendTable) -> dict[str, np.ndarray]:
    """Per programmed segment: its trimmed ends, whether it is trimmed, a line, kept; per blend its index."""
    segments, n = program.segments, len(program.segments)
    at = np.full(n + 1, -1, dtype=np.intp)
    at[blends.junction] = np.arange(len(blends))
    blend_start, blend_end = blends.start_m, blends.end_m
    start = np.array([segment.start_m for segment in segments])
    end = np.array([segment.end_m for segment in segments])
    before, after = at[:-1] >= 0, at[1:] >= 0
    start[before], end[after] = blend_end[at[:-1][before]], blend_start[at[1:][after]]
    line = np.array([isinstance(segment, LineSegment) for segment in segments])
    trimmed = before | after
    delta = end - start
    unit = np.array([segment.unit_vector if isinstance(segment, LineSegment) else np.zeros(program.n_axes)
                     for segment in segments])
    dropped = trimmed & line & ((np.sqrt(np.einsum("ij,ij->i", delta, delta)) < MIN_LENGTH_M)
                                | (np.einsum("ij,ij->i", delta, unit) <= 0.0))
    return {"at": at, "start": start, "end": end, "line": line, "trimmed": trimmed, "kept": ~dropped,
            "blend_end": blend_end}


def _slots(program: Program, pieces: dict[str, np.ndarray]) -> tuple[np.ndarray, FloatArray]:
    """The planned sequence as slots (``2k``: blend before ``k``, ``2k + 1``: segment ``k``) and each one's start.

    Returns the present slots in order and, per present slot, where the planned path is before it (m).
    """
    n = len(program.segments)
    present = np.zeros(2 * n, dtype=bool)
    present[0::2], present[1::2] = pieces["at"][:-1] >= 0, pieces["kept"]
    ends = np.empty((2 * n, program.n_axes))
    ends[1::2] = pieces["end"]
    has = pieces["at"][:-1] >= 0
    ends[0::2][has] = pieces["blend_end"][pieces["at"][:-1][has]]
    order = np.flatnonzero(present)
    previous_end = np.vstack([program.segments[0].start_m[None, :], ends[order[:-1]]])
    return order, previous_end


def _blend_arcs(program: Program, blends: BlendTable, start_m: FloatArray) -> Sequence[Segment]:
    """The blend arcs from ``start_m`` (``(M, n_axes)``, m, where the path is) to each blend's end."""
    segments, junction = program.segments, blends.junction.tolist()
    feed = np.array([segment.feed_m_s for segment in segments])
    return arc_segments(start_m, blends.end_m, blends.center_m, blends.clockwise, blends.plane,
                        np.minimum(feed[blends.junction - 1], feed[blends.junction]),
                        [segments[k].source_line for k in junction])


def _trimmed(program: Program, pieces: dict[str, np.ndarray]) -> dict[int, Segment]:
    """Every trimmed, kept segment by programmed index: lines and arcs (centre, radius and direction kept)."""
    segments = program.segments
    lines = np.flatnonzero(pieces["trimmed"] & pieces["line"] & pieces["kept"])
    arcs = np.flatnonzero(pieces["trimmed"] & ~pieces["line"])
    out: dict[int, Segment] = dict(zip(lines.tolist(), line_segments(
        pieces["start"][lines], pieces["end"][lines], np.array([segments[k].feed_m_s for k in lines]),
        [segments[k].source_line for k in lines])))
    if arcs.size:
        chosen = [cast(ArcSegment, segments[k]) for k in arcs]
        out.update(zip(arcs.tolist(), arc_segments(
            pieces["start"][arcs], pieces["end"][arcs], np.array([a.center_m for a in chosen]),
            np.array([a.clockwise for a in chosen], dtype=np.bool_), np.array([a.plane for a in chosen], dtype=np.intp),
            np.array([a.feed_m_s for a in chosen]), [a.source_line for a in chosen])))
    return out


def planned_segments(program: Program, blends: BlendTable) -> tuple[list[Segment], list[int], list[int]]:
    """Planned segments, per programmed junction the planned index after it, per planned segment its source.

    Parameters
    ----------
    program : Program
        The programmed contour.
    blends : BlendTable
        At least one blend, in junction order, at junctions in ``[1, n_segments - 1]``.

    Returns
    -------
    segments : list of LineSegment or ArcSegment
        The planned contour.
    first_after : list of int, length n_segments
        Per programmed segment ``k``, the planned index of its (trimmed) piece, or of what follows if dropped.
    sources : list of int
        Per planned segment, the programmed segment it comes from (a blend arc: the one after its corner).
    """
    pieces = _pieces(program, blends)
    order, previous_end = _slots(program, pieces)
    is_blend = order % 2 == 0
    several = blends.has_pieces
    one = np.flatnonzero(~several)
    arcs = iter(_blend_arcs(program, blends.subset(~several), previous_end[is_blend][one]))
    trimmed = _trimmed(program, pieces)
    segments = program.segments
    out: list[Segment] = []
    sources: list[int] = []
    position = []
    row = 0
    for slot in order.tolist():
        position.append(len(out))
        if slot % 2 == 0:
            chain = blends.pieces[row]
            row += 1
            added: Sequence[Segment] = [next(arcs)] if chain is None else chain
        else:
            added = [trimmed.get(slot // 2, segments[slot // 2])]
        out.extend(added)
        sources.extend([slot // 2] * len(added))
    position.append(len(out))
    first_after = np.asarray(position)[np.searchsorted(order, 2 * np.arange(len(segments)) + 1)].tolist()
    return out, first_after, sources
