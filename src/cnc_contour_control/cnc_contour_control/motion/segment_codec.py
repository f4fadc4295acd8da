"""Segments to plain arrays and lists and back, bit for bit: how a plan crosses to another process (ROS-free).

A list of :data:`~cnc_contour_control.motion.geometry.Segment` pickles one object and a few small arrays per
segment; pickling them is one C call that holds the interpreter lock for the whole list (about 10 µs a segment),
which a 1 ms tick beside it cannot wait for. :func:`encode_segments` reads every field (the derived ones too) into
one array or list per field and segment class, in Python bytecode that yields the lock at the switch interval;
such a batch pickles as a few large buffers. :func:`decode_segments` rebuilds the segments with
``from_validated``-style construction (no checks, nothing derived again), so each field is the value it was.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from cnc_contour_control.motion.arc import ArcSegment
from cnc_contour_control.motion.geometry import LineSegment, Segment

#: The segment classes a batch may hold, by the name a batch carries.
SEGMENT_CLASSES: dict[str, type] = {"line": LineSegment, "arc": ArcSegment}
_NAMES = {cls: name for name, cls in SEGMENT_CLASSES.items()}
_FIELDS = {name: tuple(f.name for f in dataclasses.fields(cls)) for name, cls in SEGMENT_CLASSES.items()}


def encode_segments(segments: list[Segment]) -> dict[str, Any]:
    """``segments`` as ``{"count": N, <class name>: {"rows": [...], <field>: array or list}}``.

    Array fields (points, directions) become one read-only ``(M, n_axes)`` array per class; the others (floats,
    source lines, planes) lists.
    """
    rows: dict[str, list[int]] = {}
    for i, segment in enumerate(segments):
        rows.setdefault(_NAMES[type(segment)], []).append(i)
    batch: dict[str, Any] = {"count": len(segments)}
    for name, indices in rows.items():
        members = [segments[i].__dict__ for i in indices]
        columns: dict[str, Any] = {"rows": indices}
        for field in _FIELDS[name]:
            values = [member[field] for member in members]
            columns[field] = np.stack(values) if isinstance(values[0], np.ndarray) else values
        batch[name] = columns
    return batch


def decode_segments(batch: dict[str, Any]) -> list[Segment]:
    """The segments :func:`encode_segments` read, in their order, each field the value it was."""
    out: list[Any] = [None] * int(batch["count"])
    for name, cls in SEGMENT_CLASSES.items():
        columns = batch.get(name)
        if columns is None:
            continue
        fields = _FIELDS[name]
        for array in (columns[f] for f in fields if isinstance(columns[f], np.ndarray)):
            array.setflags(write=False)
        for k, i in enumerate(columns["rows"]):
            segment: Any = object.__new__(cls)
            segment.__dict__.update({f: columns[f][k] for f in fields})
            out[i] = segment
    return out
