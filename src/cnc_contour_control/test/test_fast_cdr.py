"""The generated CDR codecs against rclpy's own serialization, on random messages of every type the suite sends."""
from __future__ import annotations

import importlib
import math
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message
from rosidl_parser import definition as idl

from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.nodes import fast_cdr

MSG_DIR = Path(__file__).resolve().parents[2] / "cnc_contour_interfaces" / "msg"
SUITE_TYPES = [getattr(importlib.import_module("cnc_contour_interfaces.msg"), p.stem)
               for p in sorted(MSG_DIR.glob("*.msg"))]
STANDARD_TYPES = [getattr(importlib.import_module(module), name) for module, name in (
    ("sensor_msgs.msg", "JointState"), ("trajectory_msgs.msg", "JointTrajectory"),
    ("diagnostic_msgs.msg", "DiagnosticArray"), ("std_msgs.msg", "Float64"), ("std_msgs.msg", "Bool"),
    ("std_msgs.msg", "Empty"),
    ("builtin_interfaces.msg", "Time"), ("rosgraph_msgs.msg", "Clock"))]
TYPES = SUITE_TYPES + STANDARD_TYPES
_INT_BITS = {"int8": (True, 8), "uint8": (False, 8), "int16": (True, 16), "uint16": (False, 16),
             "int32": (True, 32), "uint32": (False, 32), "int64": (True, 64), "uint64": (False, 64)}
_TEXT = st.text(st.characters(blacklist_characters="\x00", blacklist_categories=("Cs",)), max_size=12)


def _basic(typename: str) -> st.SearchStrategy[Any]:
    if typename == "boolean":
        return st.booleans()
    if typename == "octet":
        return st.binary(min_size=1, max_size=1)
    if typename in ("float", "double"):
        return st.floats(width=32 if typename == "float" else 64)
    signed, bits = _INT_BITS[typename]
    return st.integers(-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else st.integers(0, 2 ** bits - 1)


def _draw(data: st.DataObject, slot_type: Any) -> Any:
    """A random value of one field type (nested messages built recursively)."""
    if isinstance(slot_type, idl.BasicType):
        return data.draw(_basic(slot_type.typename))
    if isinstance(slot_type, (idl.UnboundedString, idl.BoundedString)):
        return data.draw(_TEXT)
    if isinstance(slot_type, idl.NamespacedType):
        return _message(data, getattr(importlib.import_module(".".join(slot_type.namespaces)), slot_type.name))
    if isinstance(slot_type, idl.Array):
        return [_draw(data, slot_type.value_type) for _ in range(slot_type.size)]
    size = data.draw(st.integers(0, 3))
    return [_draw(data, slot_type.value_type) for _ in range(size)]


def _message(data: st.DataObject, cls: type) -> Any:
    msg = cls()
    for name, slot_type in zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES):  # type: ignore[attr-defined]  # a rosidl message class
        setattr(msg, name, _draw(data, slot_type))
    return msg


@pytest.fixture(autouse=True)
def codecs_on(monkeypatch: pytest.MonkeyPatch) -> None:
    """The codecs are on unless ``CNC_FAST_CDR=0``; these tests test them whatever the environment says."""
    monkeypatch.setenv("CNC_FAST_CDR", "1")


def _has_nan(msg: Any) -> bool:
    return "nan" in repr(msg).lower()


def test_every_type_the_suite_sends_has_a_codec() -> None:
    missing = [t.__name__ for t in TYPES if fast_cdr.codec_for(t) is None]
    assert not missing


@pytest.mark.parametrize("cls", TYPES, ids=lambda t: t.__name__)
@settings(max_examples=25, deadline=None)
@given(data=st.data())
def test_codec_agrees_with_rclpy_both_ways(cls: type, data: st.DataObject) -> None:
    msg = _message(data, cls)
    codec = fast_cdr.codec_for(cls)
    assert codec is not None
    ours, theirs = codec.encode(msg), serialize_message(msg)
    # rclpy's buffer is Fast CDR's size estimate (empty sequences aligned), its padding bytes uninitialised
    assert len(ours) <= len(theirs)
    read_by_rclpy = deserialize_message(ours, cls)
    read_by_us = codec.decode(theirs)
    assert codec.encode(read_by_rclpy) == ours  # rclpy reads our bytes as we meant them (NaN bit for bit)
    assert codec.encode(read_by_us) == ours
    reference = deserialize_message(theirs, cls)
    for name in cls.get_fields_and_field_types():  # type: ignore[attr-defined]  # a rosidl message class
        assert type(getattr(read_by_us, name)) is type(getattr(reference, name)), name
    if not _has_nan(msg):
        assert read_by_us == reference
        assert read_by_rclpy == msg


@pytest.mark.parametrize("cls", TYPES, ids=lambda t: t.__name__)
def test_a_new_message_is_the_classs_own_default_and_owns_its_fields(cls: type) -> None:
    new = fast_cdr.constructor(cls)
    first, second, reference = new(), new(), cls()
    assert type(first) is cls and first == reference
    for name in cls.get_fields_and_field_types():
        assert type(getattr(first, name)) is type(getattr(reference, name)), name
        value = getattr(first, name)
        if not isinstance(value, (bool, int, float, str, bytes)):  # a sequence, array or message: never shared
            assert value is not getattr(second, name), name


@pytest.mark.parametrize("cls", SUITE_TYPES, ids=lambda t: t.__name__)
def test_a_truncated_buffer_is_refused_naming_the_type(cls: type) -> None:
    codec = fast_cdr.codec_for(cls)
    assert codec is not None
    data = codec.encode(cls())
    with pytest.raises(FaultError, match=f"{cls.__name__}: (truncated|malformed) CDR"):
        codec.decode(data[:-1])


def test_a_foreign_encapsulation_is_refused() -> None:
    from std_msgs.msg import Float64

    codec = fast_cdr.codec_for(Float64)
    assert codec is not None
    with pytest.raises(FaultError, match="not little-endian CDR"):
        codec.decode(b"\x00\x00\x00\x00" + bytes(8))


def test_cnc_fast_cdr_0_turns_the_codecs_off(monkeypatch: pytest.MonkeyPatch) -> None:
    from std_msgs.msg import Float64

    monkeypatch.setenv("CNC_FAST_CDR", "0")
    assert fast_cdr.codec_for(Float64) is None


def test_a_publisher_of_another_type_keeps_rclpys_refusal() -> None:
    from std_msgs.msg import Float64

    sent: list[Any] = []

    class Recorder:
        def publish(self, msg: Any) -> None:
            sent.append(msg)

    publisher = fast_cdr.fast_publisher(Recorder(), Float64)
    publisher.publish(Float64(data=math.pi))
    publisher.publish("not a Float64")
    assert deserialize_message(sent[0], Float64).data == math.pi
    assert sent[1] == "not a Float64"  # rclpy's publish raises its TypeError for it


def test_a_raw_subscription_that_does_not_decode_faults_with_the_topic() -> None:
    from std_msgs.msg import Float64

    faults: list[str] = []
    got: list[Any] = []
    callback, options = fast_cdr.decoding(Float64, "/cnc/x", got.append, {}, faults.append)
    assert options == {"raw": True}
    callback(serialize_message(Float64(data=2.0)))
    callback(b"\x00\x01\x00\x00\x01")
    assert [m.data for m in got] == [2.0]
    assert faults and faults[0].startswith("/cnc/x: std_msgs/Float64: truncated CDR")
    unchanged, kept = fast_cdr.decoding(Float64, "/cnc/x", got.append, {"raw": True}, faults.append)
    assert unchanged == got.append and kept == {"raw": True}
