"""CDR encoding and decoding of rosidl Python messages, generated per type: rclpy's bytes, a fraction of its time.

rclpy's ``serialize_message`` / ``deserialize_message`` convert every message
through C structures and build every nested object with keyword checks:
16-28 µs to serialize and 34-41 µs to deserialize one of the suite's small
messages, most of a lockstep hop's Python cost. This module generates, once
per message class, two straight-line Python functions from the class's own
introspection (``SLOT_TYPES``, rosidl_parser definitions):

* ``encode(msg) -> bytes``: the little-endian CDR of ``serialize_message``
  (4-byte encapsulation header, then each field aligned to its size relative
  to the payload, as Fast CDR writes it), runs of fixed-size fields packed by
  one precompiled :class:`struct.Struct` per alignment residue;
* ``decode(buf) -> msg``: a message equal to ``deserialize_message``'s, with
  the same Python types (``array.array`` for numeric sequences, NumPy arrays
  for fixed numeric arrays, lists of str and of nested messages), built with
  ``cls.__new__`` and its slots set directly (field checks off, as rclpy's
  own messages are by default).

Types it cannot do (wide strings, sequences of octets or chars) give no
codec: :func:`codec_for` returns None and callers use rclpy. Tested byte for
byte against rclpy (``test_fast_cdr.py``). On by default; ``CNC_FAST_CDR=0`` turns it off (rclpy's own conversion).
"""
from __future__ import annotations

import array
import importlib
import os
import struct
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from rosidl_parser import definition as idl

from cnc_contour_control.core.errors import FaultError

#: Fixed-size basic types: (struct code, size = alignment, array.array typecode or None).
_BASIC: dict[str, tuple[str, int, str | None]] = {
    "boolean": ("?", 1, None), "octet": ("c", 1, None),
    "float": ("f", 4, "f"), "double": ("d", 8, "d"),
    "int8": ("b", 1, "b"), "uint8": ("B", 1, "B"), "int16": ("h", 2, "h"), "uint16": ("H", 2, "H"),
    "int32": ("i", 4, "i"), "uint32": ("I", 4, "I"), "int64": ("q", 8, "q"), "uint64": ("Q", 8, "Q"),
}
#: NumPy dtypes of fixed numeric arrays, as rosidl's Python messages hold them.
_DTYPES = {"float": "<f4", "double": "<f8", "int8": "<i1", "uint8": "<u1", "int16": "<i2", "uint16": "<u2",
           "int32": "<i4", "uint32": "<u4", "int64": "<i8", "uint64": "<u8"}
_HEADER = b"\x00\x01\x00\x00"  # CDR, little endian
_U32 = struct.Struct("<I")


class Unsupported(Exception):
    """A field type this module does not generate code for (the caller falls back to rclpy)."""


@dataclass(frozen=True)
class Codec:
    """The generated functions of one message class: encode, decode, and a new message at its defaults."""

    msg_type: type
    encode_into: Callable[[bytearray, Any], None]
    decode_from: Callable[[memoryview, int], tuple[Any, int]]
    new: Callable[[], Any]

    def encode(self, msg: Any) -> bytes:
        """The serialized message, as ``rclpy.serialization.serialize_message`` gives it."""
        buf = bytearray(_HEADER)
        self.encode_into(buf, msg)
        return bytes(buf)

    def decode(self, data: bytes | bytearray | memoryview) -> Any:
        """The message of ``data``; a :class:`FaultError` naming the type for a truncated or foreign buffer."""
        view = memoryview(data)
        if len(view) < 4 or view[0] != 0 or view[1] != 1:
            raise FaultError(f"{self.name}: not little-endian CDR (header {bytes(view[:4])!r}, {len(view)} bytes)")
        try:
            msg, end = self.decode_from(view, 0)
        except (struct.error, IndexError) as err:
            raise FaultError(f"{self.name}: truncated CDR: {len(view)} bytes ({err})") from err
        except ValueError as err:  # UnicodeDecodeError too
            raise FaultError(f"{self.name}: malformed CDR in {len(view)} bytes ({err})") from err
        if end + 4 > len(view):
            raise FaultError(f"{self.name}: truncated CDR: {len(view)} bytes, the fields need {end + 4}")
        return msg

    @property
    def name(self) -> str:
        """``pkg/Name`` of the message type, as errors name it."""
        return f"{self.msg_type.__module__.split('.')[0]}/{self.msg_type.__name__}"


class _Source:
    """Python source of one function, line by line, and the constants it refers to."""

    def __init__(self, consts: dict[str, Any]) -> None:
        self.lines: list[str] = []
        self.consts = consts

    def const(self, value: Any) -> str:
        name = f"_k{len(self.consts)}"
        self.consts[name] = value
        return name

    def add(self, line: str, indent: int = 1) -> None:
        self.lines.append("    " * indent + line)


def _runs(struct_codes: list[tuple[str, int]]) -> tuple[struct.Struct, ...]:
    """One Struct per residue of the start offset mod 8, padding each field to its size."""
    structs = []
    for residue in range(8):
        offset, fmt = residue, "<"
        for code, size in struct_codes:
            pad = (-offset) % size
            fmt += "x" * pad + code
            offset += pad + size
        structs.append(struct.Struct(fmt))
    return tuple(structs)


def _module_class(namespaced: idl.NamespacedType) -> type:
    module = importlib.import_module(".".join(namespaced.namespaces))
    return getattr(module, namespaced.name)


class _Generator:
    """Generates the encode and decode functions of a class and of every class it nests."""

    def __init__(self) -> None:
        self.consts: dict[str, Any] = {"_U32": _U32, "_array": array.array, "_np": np}
        self.done: set[type] = set()
        self.sources: list[str] = []

    def ensure(self, cls: type) -> str:
        """The base name of ``cls``'s generated functions (generated once)."""
        base = f"{cls.__module__.replace('.', '_')}_{cls.__name__}"
        if cls not in self.done:
            self.done.add(cls)
            self.consts[f"_cls_{base}"] = cls
            self._generate(cls, base)
        return base

    def _generate(self, cls: type, base: str) -> None:
        fields = list(zip(cls.__slots__, cls.SLOT_TYPES))  # type: ignore[attr-defined]  # a rosidl message class
        enc, dec = _Source(self.consts), _Source(self.consts)
        dec.add(f"o = _cls_{base}.__new__(_cls_{base})")
        dec.add("o._check_fields = False")
        self._new(cls, base, fields)
        run: list[tuple[str, str, int]] = []
        for slot, slot_type in fields:
            basic = _basic_name(slot_type)
            if basic is not None:
                code, size, _ = _BASIC[basic]
                run.append((slot, code, size))
                continue
            self._flush_run(run, enc, dec)
            run = []
            self._field(slot, slot_type, enc, dec)
        self._flush_run(run, enc, dec)
        if not fields:  # an empty message: rosidl's C struct holds one placeholder byte, and CDR carries it
            enc.add("buf.append(0)")
            dec.add("off += 1")
        dec.add("return o, off")
        self.sources.append(f"def enc_{base}(buf, m):\n" + ("\n".join(enc.lines) or "    pass"))
        self.sources.append(f"def dec_{base}(buf, off):\n" + "\n".join(dec.lines))

    def _new(self, cls: type, base: str, fields: list[tuple[str, Any]]) -> None:
        """``new_<base>()``: what ``cls()`` gives (each field at the class's default), without its checks.

        Defaults are read from one ``cls()``; mutable ones are copied per message.
        """
        new, proto = _Source(self.consts), cls()
        new.add(f"o = _cls_{base}.__new__(_cls_{base})")
        new.add("o._check_fields = False")
        for slot, slot_type in fields:
            value = getattr(proto, slot)
            if isinstance(slot_type, idl.NamespacedType):
                new.add(f"o.{slot} = new_{self.ensure(_module_class(slot_type))}()")
            elif isinstance(value, (bool, int, float, str, bytes)):
                new.add(f"o.{slot} = {new.const(value)}")
            elif isinstance(value, array.array):
                new.add(f"o.{slot} = _array({value.typecode!r}, {new.const(value)})")
            elif isinstance(value, np.ndarray):
                new.add(f"o.{slot} = {new.const(value)}.copy()")
            elif isinstance(value, list) and all(isinstance(v, (bool, int, float, str, bytes)) for v in value):
                new.add(f"o.{slot} = list({new.const(value)})")
            else:
                raise Unsupported(f"{slot}: default {value!r}")
        new.add("return o")
        self.sources.append(f"def new_{base}():\n" + "\n".join(new.lines))

    def _flush_run(self, run: list[tuple[str, str, int]], enc: _Source, dec: _Source) -> None:
        if not run:
            return
        structs = enc.const(_runs([(code, size) for _, code, size in run]))
        values = ", ".join(f"m.{slot}" for slot, _, _ in run)
        enc.add(f"buf += {structs}[(len(buf) - 4) & 7].pack({values})")
        targets = ", ".join(f"o.{slot}" for slot, _, _ in run)
        dec.add(f"s = {structs}[off & 7]")
        dec.add(f"({targets},) = s.unpack_from(buf, off + 4)")
        dec.add("off += s.size")

    def _field(self, slot: str, slot_type: Any, enc: _Source, dec: _Source) -> None:
        if isinstance(slot_type, idl.NamespacedType):
            nested = self.ensure(_module_class(slot_type))
            enc.add(f"enc_{nested}(buf, m.{slot})")
            dec.add(f"o.{slot}, off = dec_{nested}(buf, off)")
        elif isinstance(slot_type, (idl.UnboundedString, idl.BoundedString)):
            _string(f"m.{slot}", f"o.{slot}", enc, dec, 1)
        elif isinstance(slot_type, (idl.UnboundedSequence, idl.BoundedSequence)):
            self._sequence(slot, slot_type.value_type, enc, dec)
        elif isinstance(slot_type, idl.Array):
            self._array(slot, slot_type, enc, dec)
        else:
            raise Unsupported(f"{slot}: {type(slot_type).__name__}")

    def _sequence(self, slot: str, value_type: Any, enc: _Source, dec: _Source) -> None:
        enc.add(f"v = m.{slot}")
        enc.add("buf += b'\\0' * ((4 - len(buf)) & 3)")
        enc.add("buf += _U32.pack(len(v))")
        dec.add("off += -off & 3")
        dec.add("n = _U32.unpack_from(buf, off + 4)[0]")
        dec.add("off += 4")
        basic = _basic_name(value_type)
        if basic is not None and _BASIC[basic][2] is not None:
            code, size, typecode = _BASIC[basic]
            _numeric_block(f"o.{slot}", code, size, typecode, enc, dec, sequence=True)
        elif isinstance(value_type, (idl.UnboundedString, idl.BoundedString)):
            enc.add("for e in v:")
            _string("e", "e", enc, None, 2)
            dec.add(f"o.{slot} = items = []")
            dec.add("for _ in range(n):")
            _string(None, "e", None, dec, 2)
            dec.add("items.append(e)", 2)
        elif isinstance(value_type, idl.NamespacedType):
            nested = self.ensure(_module_class(value_type))
            enc.add("for e in v:")
            enc.add(f"enc_{nested}(buf, e)", 2)
            dec.add(f"o.{slot} = items = []")
            dec.add("for _ in range(n):")
            dec.add(f"e, off = dec_{nested}(buf, off)", 2)
            dec.add("items.append(e)", 2)
        else:
            raise Unsupported(f"{slot}: sequence of {value_type!r}")

    def _array(self, slot: str, slot_type: idl.Array, enc: _Source, dec: _Source) -> None:
        basic = _basic_name(slot_type.value_type)
        if basic is None or _BASIC[basic][2] is None:
            raise Unsupported(f"{slot}: array of {slot_type.value_type!r}")
        code, size, _ = _BASIC[basic]
        dtype = dec.const(np.dtype(_DTYPES[basic]))
        count = slot_type.size
        enc.add(f"v = m.{slot}")
        enc.add(f"buf += b'\\0' * (-(len(buf) - 4) & {size - 1})")
        enc.add(f"buf += _np.asarray(v, dtype={dtype}).tobytes()")
        dec.add(f"off += -off & {size - 1}")
        dec.add(f"o.{slot} = _np.frombuffer(buf, dtype={dtype}, count={count}, offset=off + 4).copy()")
        dec.add(f"off += {count * size}")


def _numeric_block(target: str, code: str, size: int, typecode: str | None, enc: _Source, dec: _Source,
                   sequence: bool) -> None:
    """The elements of a numeric sequence (its length already written), as array.array.

    An empty sequence is not aligned (what Fast CDR writes; rclpy's buffer may
    still be longer: its size is Fast CDR's estimate, which aligns empty
    sequences, and the bytes past the data are not initialised).
    """
    enc.add("if v:")
    enc.add(f"buf += b'\\0' * (-(len(buf) - 4) & {size - 1})", 2)
    enc.add(f"buf += v.tobytes() if type(v) is _array and v.typecode == {typecode!r} "
            f"else _array({typecode!r}, v).tobytes()", 2)
    dec.add(f"a = _array({typecode!r})")
    dec.add("if n:")
    dec.add(f"off += -off & {size - 1}", 2)
    dec.add(f"a.frombytes(buf[off + 4:off + 4 + n * {size}])", 2)
    dec.add(f"off += n * {size}", 2)
    dec.add(f"{target} = a")


def _string(source: str | None, target: str, enc: _Source | None, dec: _Source | None, indent: int) -> None:
    """One string: aligned uint32 length (with the NUL), UTF-8 bytes, NUL."""
    if enc is not None:
        enc.add(f"b = {source}.encode()", indent)
        enc.add("buf += b'\\0' * ((4 - len(buf)) & 3)", indent)
        enc.add("buf += _U32.pack(len(b) + 1)", indent)
        enc.add("buf += b", indent)
        enc.add("buf.append(0)", indent)
    if dec is not None:
        dec.add("off += -off & 3", indent)
        dec.add("k = _U32.unpack_from(buf, off + 4)[0]", indent)
        dec.add(f"{target} = str(buf[off + 8:off + 7 + k], 'utf-8')", indent)
        dec.add("off += 4 + k", indent)


def _basic_name(slot_type: Any) -> str | None:
    """The typename of a fixed-size basic type, None for anything else (char is not supported)."""
    if isinstance(slot_type, idl.BasicType):
        if slot_type.typename not in _BASIC:
            raise Unsupported(slot_type.typename)
        return str(slot_type.typename)
    return None


_CODECS: dict[type, Codec | None] = {}


def enabled() -> bool:
    """True on a little-endian host unless ``CNC_FAST_CDR=0`` (then every message goes through rclpy).

    (Opt-in for a while: a recorder that never saw a fast run's end turned out
    to be a reader of ``/diagnostics`` matched after the run ended, not the
    codecs: docs/design.md §5.)
    """
    return os.environ.get("CNC_FAST_CDR", "1") != "0" and sys.byteorder == "little"


def codec_for(msg_type: type) -> Codec | None:
    """The generated codec of ``msg_type`` (cached), or None if a field type is not supported or codecs are off."""
    if not enabled():
        return None
    if msg_type not in _CODECS:
        _CODECS[msg_type] = _build(msg_type)
    return _CODECS[msg_type]


def _build(msg_type: type) -> Codec | None:
    generator = _Generator()
    try:
        base = generator.ensure(msg_type)
    except Unsupported:
        return None
    namespace = dict(generator.consts)
    exec(compile("\n\n".join(generator.sources), f"<fast_cdr {msg_type.__name__}>", "exec"), namespace)
    return Codec(msg_type, namespace[f"enc_{base}"], namespace[f"dec_{base}"], namespace[f"new_{base}"])


class FastPublisher:
    """An rclpy publisher that publishes its type's messages as bytes encoded here (rclpy's ``publish_raw``).

    Everything else (``topic_name``, ``get_subscription_count``,
    ``wait_for_all_acked``...) is the rclpy publisher's; a message of another
    type goes to rclpy, which refuses it as usual.
    """

    def __init__(self, publisher: Any, codec: Codec) -> None:
        self.publisher, self.codec = publisher, codec

    def __getattr__(self, name: str) -> Any:
        return getattr(self.publisher, name)

    def publish(self, msg: Any) -> None:
        """Encode and publish ``msg`` (bytes and foreign types go to rclpy unchanged)."""
        self.publisher.publish(self.codec.encode(msg) if type(msg) is self.codec.msg_type else msg)


def fast_publisher(publisher: Any, msg_type: type) -> Any:
    """``publisher`` wrapped in a :class:`FastPublisher` when ``msg_type`` has a codec, else unchanged."""
    codec = codec_for(msg_type)
    return publisher if codec is None else FastPublisher(publisher, codec)


def decoding(msg_type: type, topic: str, callback: Callable[[Any], Any], options: dict[str, Any],
             on_fault: Callable[[str], Any]) -> tuple[Callable[[Any], Any], dict[str, Any]]:
    """A raw subscription's callback and options that decode here and call ``callback`` with the message.

    Unchanged when the caller asked for raw bytes or the type has no codec. A
    buffer that does not decode calls ``on_fault`` with the topic and the reason.
    """
    codec = None if options.get("raw") else codec_for(msg_type)
    if codec is None:
        return callback, options
    decode = codec.decode

    def receive(data: bytes) -> None:
        try:
            msg = decode(data)
        except FaultError as err:
            on_fault(f"{topic}: {err}")
            return
        callback(msg)

    return receive, {**options, "raw": True}


def constructor(msg_type: type) -> Callable[[], Any]:
    """A function giving a new ``msg_type`` equal to ``msg_type()``: the codec's (a fraction of the time of rosidl's
    ``__init__``, which checks its keywords and sets every field through its property), else the class itself."""
    codec = codec_for(msg_type)
    return msg_type if codec is None else codec.new


def encoder(msg_type: type) -> Callable[[Any], bytes] | None:
    """The encode function of ``msg_type``'s codec, or None (then rclpy's ``serialize_message``)."""
    codec = codec_for(msg_type)
    return None if codec is None else codec.encode
