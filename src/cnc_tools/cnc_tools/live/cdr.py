"""CDR of many messages at once: a message's bytes with its strings and sequence lengths fixed, numbers filled by numpy.

In CDR (little endian, ``ros2msg``) a field's offset depends only on the fields before it: on string lengths and
sequence lengths, never on numbers. An engine run's messages of one topic keep their strings (frame, axis names,
law) and lengths from tick to tick, so :class:`CdrTemplate` serialises one sample message with rosbags (the bags'
serialiser: the bytes are the bag's by construction), walks the type's definition for the offset of every numeric
field, and :meth:`CdrTemplate.fill` writes a whole batch of ticks into copies of those bytes, one numpy assignment
per field. ``test_live`` holds the streamed bytes equal to the bag's.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Size in bytes of each numeric ROS base type, and the numpy type CDR (little endian) holds it as.
_NUMERIC = {"bool": (1, "u1"), "byte": (1, "u1"), "char": (1, "u1"), "int8": (1, "i1"), "uint8": (1, "u1"),
            "int16": (2, "<i2"), "uint16": (2, "<u2"), "int32": (4, "<i4"), "uint32": (4, "<u4"),
            "int64": (8, "<i8"), "uint64": (8, "<u8"), "float32": (4, "<f4"), "float64": (8, "<f8")}
#: Bytes before the body (the encapsulation header); alignment counts from after them.
_ENCAPSULATION = 4
_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4


@dataclass(frozen=True)
class Field:
    """Where a numeric field lies in the message's bytes: offset, numpy type, count (elements of an array)."""

    offset: int
    dtype: str
    count: int


def _align(position: int, size: int) -> int:
    return position + (-position) % size


class CdrTemplate:
    """One message type's CDR with the strings and lengths of ``sample``; numbers by field path (``header.stamp.sec``,
    ``position``, ``wrench.force.x``). A path the batch does not give keeps the sample's value."""

    def __init__(self, store: Any, type_name: str, sample: Any) -> None:
        self.type_name = type_name
        self.template = np.frombuffer(bytes(store.serialize_cdr(sample, type_name)), np.uint8)
        self.fields: dict[str, Field] = {}
        end = self._walk(store, type_name, sample, "", 0)
        if end + _ENCAPSULATION != self.template.size:
            raise ValueError(f"CDR layout of {type_name}: walked {end + _ENCAPSULATION} bytes, rosbags wrote "
                             f"{self.template.size}")

    def _walk(self, store: Any, type_name: str, message: Any, prefix: str, position: int) -> int:
        """Record the numeric fields of ``message`` from body offset ``position``; the offset after it."""
        for name, (node, desc) in store.fielddefs[type_name][1]:
            value, path = getattr(message, name), prefix + name
            if node == _NAME:
                position = self._walk(store, desc, value, path + ".", position)
                continue
            if node == _BASE:
                position = self._scalar(desc[0], value, path, position, 1)
                continue
            (inner, (base, _)), _ = desc  # an array or a sequence of base types (the suite's messages have no others)
            if inner != _BASE:
                raise ValueError(f"{type_name}.{name}: sequences of messages are not templated")
            if node == _SEQUENCE:
                position = _align(position, 4) + 4
            if base == "string":
                for text in value:
                    position = self._scalar("string", text, path, position, 1)
            else:
                position = self._scalar(base, value, path, position, len(value))
        return position

    def _scalar(self, base: str, value: Any, path: str, position: int, count: int) -> int:
        if base == "string":
            return _align(position, 4) + 4 + len(str(value).encode("utf-8")) + 1
        size, dtype = _NUMERIC[base]
        position = _align(position, size) if count else position
        self.fields[path] = Field(_ENCAPSULATION + position, dtype, count)
        return position + size * count

    def fill(self, rows: int, values: Mapping[str, Any]) -> np.ndarray:
        """``rows`` messages (uint8, one per row): the template with each given field's values, one per row (a
        column of ``rows`` for a scalar, ``rows`` x count for an array)."""
        out = np.tile(self.template, (rows, 1))
        for path, column in values.items():
            field = self.fields[path]
            data = np.ascontiguousarray(np.asarray(column).reshape(rows, field.count), field.dtype)
            out[:, field.offset:field.offset + data.itemsize * field.count] = data.view(np.uint8).reshape(rows, -1)
        return out
