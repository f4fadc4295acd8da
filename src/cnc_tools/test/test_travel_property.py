"""Issue 23: random programs in a random travel box are refused naming line, axis and excess, or stay inside.

Each example is a G-code program from the origin (lines; G2/G3 arcs of random
radius, start direction and sweep up to 1.9 turns; a random G64 P blend
tolerance, 0 to 0.5 mm; a random acceleration/deceleration filter: none,
exponential or linear, 20-200 ms) and a random box around the origin. Either the
scenario loader refuses it (the planned path, blends and arc extremes
included, leaves the box: the message names the line, the axis and the excess
in mm), or the engine runs it and

- every recorded reference sample lies in the box (within 1 nm: exactly, but
  for the rounding of cos/sin);
- every joint position lies in the box widened, per axis and tick, by that
  tick's following error |reference - position| (the position trails a
  reference that is inside); the largest excess beyond the plain box is also
  bounded by :data:`POSITION_EXCESS_BOUND_MM` (a servo's overshoot, not a path).

The test command runs a few examples; ``CNC_TRAVEL_PROGRAMS=1000`` the
measurement (the count and the samples outside are printed).
"""
from __future__ import annotations

import math
import os
import re
from typing import Any

import numpy as np
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.travel import TRAVEL_TOLERANCE_M
from cnc_tools.runs.engine import EngineFault, run_engine
from cnc_tools.runs.scenario import build_scenario

PROGRAMS = int(os.environ.get("CNC_TRAVEL_PROGRAMS", "12"))
#: A position may stand outside the box by its following error; this bounds it over every program, mm.
POSITION_EXCESS_BOUND_MM = 0.5
REFUSAL = re.compile(r"^scenario\.limits\.travel_mm: travel limit: line (\d+) takes axis ([xy]) to (-?\d+\.\d{6}) mm, "
                     r"(\d+\.\d{6}) mm beyond its travel_(min|max)_mm (-?[\d.e+-]+); refused before any axis moves$")
TALLY = {"programs": 0, "refused": 0, "ran": 0, "reference_outside": 0, "position_outside_widened": 0,
         "position_outside_box": 0, "max_position_excess_mm": 0.0}


@st.composite
def moves(draw: Any) -> str:
    """G-code lines (absolute, mm) from the origin: lines and arcs, with a random blend tolerance."""
    x, y = 0.0, 0.0
    tolerance = draw(st.sampled_from([0.0, 0.01, 0.1, 0.5]))
    out = [f"G21 G90 G17 G64 P{tolerance}" if tolerance else "G21 G90 G17 G61",
           f"G1 F{draw(st.integers(300, 2000))}"]
    for _ in range(draw(st.integers(1, 5))):
        if draw(st.booleans()):
            tx, ty = round(draw(st.floats(-25, 25)), 4), round(draw(st.floats(-25, 25)), 4)
            if math.hypot(tx - x, ty - y) > 0.01:
                out.append(f"G1 X{tx:.4f} Y{ty:.4f}")
                x, y = tx, ty
            continue
        radius, phi = draw(st.floats(0.5, 15.0)), draw(st.floats(0.0, 2 * math.pi))
        sweep = draw(st.floats(0.1, 1.9 * math.pi)) * draw(st.sampled_from([-1.0, 1.0]))
        cx, cy = round(x + radius * math.cos(phi), 4), round(y + radius * math.sin(phi), 4)
        r = math.hypot(x - cx, y - cy)
        start = math.atan2(y - cy, x - cx)
        ex, ey = round(cx + r * math.cos(start + sweep), 4), round(cy + r * math.sin(start + sweep), 4)
        out.append(f"{'G3' if sweep > 0 else 'G2'} X{ex:.4f} Y{ey:.4f} I{cx - x:.4f} J{cy - y:.4f}")
        x, y = ex, ey
    if len(out) == 2:  # no move drawn: one line
        out.append("G1 X1 Y1")
    return "\n".join(out) + "\n"


def box() -> Any:
    side = st.floats(1.0, 45.0)
    return st.tuples(side, side, side, side).map(lambda s: {"x": [-s[0], s[1]], "y": [-s[2], s[3]]})


def filters() -> Any:
    """The interpolator's acceleration/deceleration: none, or a lag or moving average of 20-200 ms."""
    return st.one_of(st.just({"kind": "none"}),
                     st.builds(lambda kind, t: {"kind": kind, "time_constant_s": t},
                               st.sampled_from(["exponential", "linear"]), st.floats(0.02, 0.2)))


def scenario(gcode: str, travel: dict[str, list[float]], accel_decel: dict[str, Any]) -> dict[str, Any]:
    """Paper 000's feed drives under PID (as scenarios/gcode_shop.yaml), T = 10 ms."""
    return {"interpolator": {"accel_decel": accel_decel},
            "name": "travel_property", "format_version": 2, "sample_time_s": 0.01, "settle_s": 0.2, "seed": 1,
            "plant": {"model": "paper000", "axes": ["x", "y"]},
            "limits": {"max_velocity_mm_min": 2000, "max_acceleration_mm_s2": 250, "travel_mm": travel},
            "servo": {"law": "pid", "law_params": {"kp": 2.4, "ki": 10.0, "kd": 0.067}},
            "program": {"axes": ["x", "y"], "gcode": gcode}}


def check_inside(record: Any, travel: dict[str, list[float]]) -> None:
    low = np.array([travel["x"][0], travel["y"][0]]) * 1e-3
    high = np.array([travel["x"][1], travel["y"][1]]) * 1e-3
    reference = record.reference.position_m
    TALLY["reference_samples"] = TALLY.get("reference_samples", 0) + len(reference)
    outside = np.any((reference < low - TRAVEL_TOLERANCE_M) | (reference > high + TRAVEL_TOLERANCE_M), axis=1)
    TALLY["reference_outside"] += int(np.count_nonzero(outside))
    assert not np.any(outside), f"reference outside the box at {np.flatnonzero(outside)[:5]}"
    stamps = np.intersect1d(record.reference.stamp_ns, record.joint_states.stamp_ns)
    ref = reference[np.searchsorted(record.reference.stamp_ns, stamps)]
    position = record.joint_states.position_m[np.searchsorted(record.joint_states.stamp_ns, stamps)]
    following = np.abs(ref - position)
    excess = np.maximum(low - position, position - high)
    TALLY["position_outside_box"] += int(np.count_nonzero(np.any(excess > TRAVEL_TOLERANCE_M, axis=1)))
    widened = np.any(excess > following + TRAVEL_TOLERANCE_M, axis=1)
    TALLY["position_outside_widened"] += int(np.count_nonzero(widened))
    TALLY["max_position_excess_mm"] = max(TALLY["max_position_excess_mm"], 1e3 * float(np.max(excess, initial=0.0)))
    assert not np.any(widened)
    assert 1e3 * float(np.max(excess, initial=0.0)) <= POSITION_EXCESS_BOUND_MM


@settings(max_examples=PROGRAMS, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(gcode=moves(), travel=box(), accel_decel=filters())
def test_a_random_program_is_refused_naming_line_axis_and_excess_or_stays_in_the_box(
        gcode: str, travel: dict[str, list[float]], accel_decel: dict[str, Any]) -> None:
    TALLY["programs"] += 1
    try:
        built = build_scenario(scenario(gcode, travel, accel_decel))
    except ConfigError as err:
        if "travel limit" not in str(err):
            TALLY["other_refusals"] = TALLY.get("other_refusals", 0) + 1  # a degenerate draw, counted
            assume(False)
        match = REFUSAL.match(str(err))
        assert match, str(err)
        line, axis, reach_mm, excess_mm, side = (int(match[1]), match[2], float(match[3]), float(match[4]),
                                                 match[5])
        bound = travel[axis][0 if side == "min" else 1]
        assert 1 <= line <= gcode.count("\n") and excess_mm >= 1e-6  # > TRAVEL_TOLERANCE_M, 1 nm
        assert abs(abs(reach_mm - bound) - excess_mm) < 2e-6
        TALLY["refused"] += 1
        return
    try:
        record = run_engine(built)
    except EngineFault as err:  # a following-error trip stops the machine: what it recorded is checked too
        record = err.record
        TALLY["tripped"] = TALLY.get("tripped", 0) + 1
    check_inside(record, travel)
    TALLY["ran"] += 1


def test_zz_report_the_tally() -> None:
    """The property test's tally (runs after it in this module): printed for the measurement."""
    print(f"\ntravel property: {TALLY}")
    assert TALLY["reference_outside"] == 0 and TALLY["position_outside_widened"] == 0
