"""The fuzzing of ``bench fuzz`` in small, under hypothesis: each input kind keeps the goal 0 / 0 / 0.

For every kind (G-code, scenario mappings, messages of the subscribed topics, damaged bags) an input is
refused with a :class:`CncError` or accepted sensibly: no other exception, no input over the time bound,
no nonsense accepted (``cnc_tools.bench.fuzz_inputs`` defines it per kind). Also the regression tests of
what the fuzzer found, and the bench's own table.
"""
from __future__ import annotations

import argparse
import math
import random
import struct
import time
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sensor_msgs.msg import JointState

from cnc_contour_control.core.errors import CncError, ConfigError, FaultError, ProgramError
from cnc_contour_control.motion.gcode import parse_gcode
from cnc_contour_control.nodes import conversions
from cnc_contour_interfaces.msg import Compensation, Reference
from cnc_tools.bagio.raw_bag import locate, read_raw
from cnc_tools.bench import fuzz, fuzz_inputs

SETTINGS = settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _check(kind: str, rng: random.Random) -> None:
    """One generated input of ``kind``: no exception but CncError (the check catches those), in time, no nonsense."""
    case = fuzz.KINDS[kind].generate(rng)
    start_s = time.perf_counter()
    finding = fuzz.KINDS[kind].check(case)
    assert time.perf_counter() - start_s < fuzz.HANG_BOUND_S, case
    assert not finding, finding


@SETTINGS
@given(rng=st.randoms(use_true_random=False))
def test_generated_gcode(rng: random.Random) -> None:
    _check("gcode", rng)


@SETTINGS
@given(text=st.text(alphabet=st.sampled_from("GXYIJKFPRMNZ0123456789.-+ ()%;\n\té"), max_size=80))
def test_gcode_text_is_refused_or_read_finite(text: str) -> None:
    try:
        program = parse_gcode(text, ("x", "y"))
    except CncError:
        return
    assert fuzz_inputs.check_gcode((text, False)) == ""
    assert all(seg.feed_m_s > 0 and math.isfinite(seg.length_m) for seg in program.segments)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rng=st.randoms(use_true_random=False))
def test_generated_scenarios(rng: random.Random) -> None:
    _check("scenario", rng)


@SETTINGS
@given(rng=st.randoms(use_true_random=False))
def test_generated_messages(rng: random.Random) -> None:
    _check("messages", rng)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rng=st.randoms(use_true_random=False))
def test_generated_damaged_bags(rng: random.Random) -> None:
    _check("bag", rng)


def _max_chunk_messages(data: bytes) -> int:
    """The most Message records any chunk of the file holds."""
    summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 20)[0]
    most, pos = 0, 8
    while pos < summary_start:
        length = struct.unpack_from("<Q", data, pos + 1)[0]
        if data[pos] == 0x06:
            count, at = 0, pos + 9 + 40
            while at < pos + 9 + length:
                count += data[at] == 0x05
                at += 9 + struct.unpack_from("<Q", data, at + 1)[0]
            most = max(most, count)
        pos += 9 + length
    return most


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(where=st.floats(0.0, 1.0, exclude_max=True), bit=st.integers(0, 7))
def test_one_flipped_bit_loses_at_most_one_chunk(tmp_path_factory: pytest.TempPathFactory, where: float,
                                                 bit: int) -> None:
    small = fuzz_inputs.small_bag()
    data = bytearray(small.data)
    data[int(where * len(data))] ^= 1 << bit
    folder = tmp_path_factory.mktemp("flip") / "small"
    folder.mkdir()
    (folder / "small.mcap").write_bytes(bytes(data))
    (folder / "metadata.yaml").write_text(small.metadata)
    _, integrity = read_raw(locate(folder), lambda topic: True)
    assert not integrity.complete
    assert integrity.lost is not None and sum(integrity.lost.values()) <= _max_chunk_messages(small.data)


# --------------------------------------------------------------------------- what the fuzzer found
@pytest.mark.parametrize("decode", [
    lambda: conversions.joint_position(JointState(name=["x", "x"], position=[0.1, math.nan]), "x"),
    lambda: conversions.joint_velocity(JointState(name=["x", "x"], position=[0.0, 0.0], velocity=[1.0, 2.0]), "x"),
    lambda: conversions.reference_axis(Reference(axis_names=["y", "y"], position_m=[0.0, 1.0],
                                                 velocity_m_s=[0.0, 0.0], acceleration_m_s2=[0.0, 0.0]), "y"),
    lambda: conversions.compensation_for(Compensation(axis_names=["x", "x"], correction=[1.0, -1.0]), "x"),
])
def test_an_axis_named_twice_is_a_fault(decode: Any) -> None:
    with pytest.raises(FaultError, match="2 times"):
        decode()


@pytest.mark.parametrize("line", ["M" + "9" * 400, "G1 X" + "9" * 400 + " F100", "G1 X1 F-" + "1" + "0" * 320])
def test_a_value_beyond_any_float_is_refused_by_line(line: str) -> None:
    """``float`` reads 310 digits as infinity; ``M`` + 400 nines raised OverflowError in ``int()``."""
    with pytest.raises(ProgramError, match=r"line 1: .*beyond any number"):
        parse_gcode(line, ("x", "y"))


def test_the_bench_prints_the_goal_per_kind(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    options = argparse.Namespace(count=20, kinds="gcode,messages", seed=3, quick=False, json=tmp_path / "f.json")
    assert fuzz.fuzz_bench(options) == 0
    out = capsys.readouterr().out
    assert "gcode" in out and "messages" in out and out.count(" met") == 2
    with pytest.raises(ConfigError, match="kinds"):
        fuzz.fuzz_bench(argparse.Namespace(count=1, kinds="gcode,yaml", seed=0, quick=False, json=None))
