"""Message types of the suite: the ``rosbags`` typestore and a columnar CDR decoder.

The typestore is ROS 2 Jazzy plus the project's custom types, registered from
the project's ``.msg`` files, found in the installed share directory
(``<prefix>/share/cnc_contour_interfaces/msg`` for each prefix of
``AMENT_PREFIX_PATH``) and, failing that, in the source tree
(``src/cnc_contour_interfaces/msg``).

``decode_columns`` turns many CDR messages of one type into numpy columns at
once: it walks the layout of one template message with the typestore's field
definitions, checks with one vectorised comparison that the other messages of
the same length share every structural byte (string lengths and contents,
sequence counts), and slices the numeric fields of all of them in one go.
Messages that differ get their own template. No rclpy, no generated classes.
"""
from __future__ import annotations

import functools
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from cnc_contour_control.core.errors import BagError, ConfigError

#: ROS package that holds the project's message definitions.
INTERFACES_PACKAGE = "cnc_contour_interfaces"

#: Source-tree location of the ``.msg`` files, relative to this file (``src/cnc_tools/cnc_tools``).
_SOURCE_MSG_DIR = Path(__file__).resolve().parents[2] / INTERFACES_PACKAGE / "msg"


def candidate_msg_dirs(ament_prefix_path: str | None = None) -> list[Path]:
    """Directories searched for the project's ``.msg`` files, in order of preference.

    Parameters
    ----------
    ament_prefix_path
        ``os.pathsep``-separated install prefixes; ``None`` reads ``AMENT_PREFIX_PATH``.

    Returns
    -------
    list of Path
        ``<prefix>/share/cnc_contour_interfaces/msg`` for every prefix, then the source tree.
    """
    if ament_prefix_path is None:
        ament_prefix_path = os.environ.get("AMENT_PREFIX_PATH", "")
    prefixes = [p for p in ament_prefix_path.split(os.pathsep) if p]
    installed = [Path(p) / "share" / INTERFACES_PACKAGE / "msg" for p in prefixes]
    return [*installed, _SOURCE_MSG_DIR]


def find_msg_dir(candidates: Sequence[Path] | None = None) -> Path:
    """Return the first candidate directory that holds ``.msg`` files.

    Raises
    ------
    ConfigError
        No candidate holds any ``.msg`` file; the message lists where it looked.
    """
    searched = list(candidates) if candidates is not None else candidate_msg_dirs()
    for directory in searched:
        if directory.is_dir() and any(directory.glob("*.msg")):
            return directory
    raise ConfigError(
        f"{INTERFACES_PACKAGE} message definitions not found; searched "
        f"{[str(d) for d in searched]} (source the workspace or set AMENT_PREFIX_PATH)"
    )


def custom_type_definitions(msg_dir: Path) -> dict[str, Any]:
    """Parse every ``.msg`` file of ``msg_dir`` into rosbags field definitions.

    Returns
    -------
    dict
        ``{"cnc_contour_interfaces/msg/<Name>": fielddefs}`` as ``Typestore.register`` takes it.
    """
    definitions: dict[str, object] = {}
    for msg_file in sorted(msg_dir.glob("*.msg")):
        type_name = f"{INTERFACES_PACKAGE}/msg/{msg_file.stem}"
        definitions.update(get_types_from_msg(msg_file.read_text(encoding="utf-8"), type_name))
    return definitions


def build_typestore(msg_dir: Path | None = None) -> Typestore:
    """Build a fresh Jazzy typestore with the project's types registered (uncached)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(custom_type_definitions(msg_dir or find_msg_dir()))
    return store


@functools.cache
def project_typestore() -> Typestore:
    """The suite's typestore, built once per process: Jazzy plus ``cnc_contour_interfaces``."""
    return build_typestore()


# --------------------------------------------------------------------------- columnar CDR decoding

#: numpy type codes of the CDR primitives (byte order is added per message).
_PRIMITIVES: dict[str, str] = {
    "bool": "?", "byte": "u1", "char": "u1", "int8": "i1", "uint8": "u1",
    "int16": "i2", "uint16": "u2", "int32": "i4", "uint32": "u4",
    "int64": "i8", "uint64": "u8", "float32": "f4", "float64": "f8",
}
#: Templates tried by vectorised comparison before the decoder falls back to one per message.
_MAX_TEMPLATES = 16


@dataclass(frozen=True, eq=False)
class ColumnBlock:
    """Messages of one layout, decoded into columns.

    Attributes
    ----------
    rows
        (R,) int, indices of these messages in the list given to ``decode_columns``.
    strings
        Field path (``"header.frame_id"``, ``"name"``) -> the string, or the tuple of
        strings of a string sequence; shared by every message of the block.
    numbers
        Field path -> (R,) array for a scalar field, (R, count) for an array or sequence.
    """

    rows: NDArray[np.int64]
    strings: Mapping[str, str | tuple[str, ...]]
    numbers: Mapping[str, NDArray[np.generic]]


class _NotColumnar(Exception):
    """The type holds a sequence of messages; decode it per message instead."""


@dataclass
class MessageLayout:
    """Where the fields of one CDR message lie.

    ``numbers`` maps a field path to ``(byte offset, count, dtype, is_scalar)``; ``strings``
    to its value(s); ``fixed`` lists the structural byte offsets (encapsulation, lengths,
    string bytes) that messages of the same layout share.
    """

    buf: bytes
    order: str
    pos: int = 4
    fixed: list[int] = field(default_factory=lambda: [0, 1])
    strings: dict[str, str | tuple[str, ...]] = field(default_factory=dict)
    numbers: dict[str, tuple[int, int, np.dtype, bool]] = field(default_factory=dict)

    def align(self, size: int) -> None:
        self.pos += (-(self.pos - 4)) % size

    def take(self, size: int) -> int:
        start, self.pos = self.pos, self.pos + size
        if size < 0 or self.pos > len(self.buf):
            raise BagError(f"CDR message of {len(self.buf)} bytes ends inside a field at byte {start}")
        return start

    def count(self) -> int:
        self.align(4)
        start = self.take(4)
        self.fixed.extend(range(start, start + 4))
        return int(np.frombuffer(self.buf, np.dtype(self.order + "u4"), 1, start)[0])

    def string(self) -> str:
        size = self.count()
        start = self.take(size)
        self.fixed.extend(range(start, start + size))
        return self.buf[start:start + max(size - 1, 0)].decode("utf-8", errors="replace")


def _walk_message(layout: MessageLayout, fielddefs: Mapping[str, Any], msgtype: str, prefix: str) -> None:
    for name, (node, desc) in fielddefs[msgtype][1]:
        _walk_field(layout, fielddefs, prefix + name, node, desc)


def _walk_field(layout: MessageLayout, fielddefs: Mapping[str, Any], path: str, node: int, desc: Any) -> None:
    if node == Nodetype.NAME:
        _walk_message(layout, fielddefs, str(desc), path + ".")
    elif node == Nodetype.BASE:
        _walk_values(layout, path, desc[0], 1, scalar=True)
    else:
        (sub_node, sub_desc), length = desc
        count = layout.count() if node == Nodetype.SEQUENCE else int(length)
        if sub_node != Nodetype.BASE:
            raise _NotColumnar(path)
        _walk_values(layout, path, sub_desc[0], count, scalar=False)


def _walk_values(layout: MessageLayout, path: str, typename: str, count: int, *, scalar: bool) -> None:
    if typename == "string":
        values = tuple(layout.string() for _ in range(count))
        layout.strings[path] = values[0] if scalar else values
        return
    if typename not in _PRIMITIVES:
        raise _NotColumnar(path)
    dtype = np.dtype(layout.order + _PRIMITIVES[typename])
    if count:
        layout.align(dtype.itemsize)
    start = layout.take(dtype.itemsize * count)
    layout.numbers[path] = (start, count, dtype, scalar)


def message_layout(buf: bytes, msgtype: str, typestore: Typestore) -> MessageLayout:
    """Walk one CDR message of ``msgtype``; raise ``BagError`` if it is malformed."""
    if len(buf) < 4 or buf[0] != 0 or buf[1] not in (0, 1):
        raise BagError(f"{msgtype}: not a plain CDR message (header {bytes(buf[:4])!r})")
    layout = MessageLayout(buf=bytes(buf), order="<" if buf[1] == 1 else ">")
    _walk_message(layout, typestore.fielddefs, msgtype, "")
    return layout


def _block(matrix: NDArray[np.uint8], rows: NDArray[np.int64], layout: MessageLayout) -> ColumnBlock:
    numbers: dict[str, NDArray[np.generic]] = {}
    for path, (start, count, dtype, scalar) in layout.numbers.items():
        raw = np.ascontiguousarray(matrix[:, start:start + dtype.itemsize * count])
        values = raw.view(dtype).reshape(len(rows), count).astype(dtype.newbyteorder("="))
        numbers[path] = values[:, 0] if scalar else values
    return ColumnBlock(rows=rows, strings=dict(layout.strings), numbers=numbers)


def _decode_same_length(matrix: NDArray[np.uint8], rows: NDArray[np.int64], msgtype: str,
                        typestore: Typestore) -> list[ColumnBlock]:
    blocks: list[ColumnBlock] = []
    pending = np.arange(len(rows))
    while pending.size:
        template = matrix[pending[0]]
        layout = message_layout(template.tobytes(), msgtype, typestore)
        if len(blocks) >= _MAX_TEMPLATES:
            members = pending[:1]
        else:
            fixed = np.asarray(layout.fixed, dtype=np.intp)
            members = pending[(matrix[np.ix_(pending, fixed)] == template[fixed]).all(axis=1)]
        blocks.append(_block(matrix[members], rows[members], layout))
        pending = np.setdiff1d(pending, members, assume_unique=True)
    return blocks


def decode_columns(raws: Sequence[bytes | memoryview], msgtype: str,
                   typestore: Typestore) -> list[ColumnBlock]:
    """Decode many CDR messages of one type into numeric columns.

    Parameters
    ----------
    raws
        N serialised messages (CDR with its 4-byte encapsulation header).
    msgtype
        ROS type name, e.g. ``"sensor_msgs/msg/JointState"``; it must hold no
        sequence or array of nested messages (``ConfigError`` otherwise).
    typestore
        Typestore that knows ``msgtype``.

    Returns
    -------
    list of ColumnBlock
        Blocks whose ``rows`` together cover ``range(N)`` exactly once.

    Raises
    ------
    BagError
        A message is malformed (ends inside a field, unknown encapsulation).
    """
    if msgtype not in typestore.fielddefs:
        raise ConfigError(f"message type {msgtype!r} is not in the typestore")
    lengths = np.fromiter(map(len, raws), dtype=np.int64, count=len(raws))
    blocks: list[ColumnBlock] = []
    try:
        for length in np.unique(lengths):
            rows = np.flatnonzero(lengths == length)
            joined = b"".join(raws[i] for i in rows.tolist())
            matrix = np.frombuffer(joined, dtype=np.uint8).reshape(len(rows), int(length))
            blocks.extend(_decode_same_length(matrix, rows, msgtype, typestore))
    except _NotColumnar as err:
        raise ConfigError(f"{msgtype}: field {err} holds nested messages; deserialise it instead") from err
    return blocks
