"""Issue 26: faults injected by the plant in random combinations are diagnosed at their size (engine, no DDS).

The rig: paper 003's plant (a PI velocity loop per axis) under a P position
loop of k = 60 /s, R 10 mm at 300 mm/min (ω = 0.5 rad/s), T = 2 ms, a feed-in
arc of 180°, the measured 360° turn and a feed-out arc of 180° about the
origin; faults from the plant: ``plant.faults`` (squareness, scale, backlash,
cyclic error, drive gain) and the axes' ``coulomb_mm_s``. Bound: within 5 % or
0.5 µm (a quantity's µm at R), whichever is larger.

What each fault should read, from the plant's own model:

- Coulomb friction ``c`` [mm/s] acts at the velocity loop's input (``w = u − c``),
  which the PI loop cannot see, so the P position loop carries ``c/k`` of
  following error against the motion: a lost motion of ``2c/k`` that a
  ballbar reads as backlash (docs/circular_test.md), beside its spike;
- a drive gain error ``g`` makes that axis's loop gain ``k(1 + g)``: the servo
  mismatch is ``(v/2)(1/k_x − 1/k_y)`` (Eq. 8), and the friction's lost motion
  ``2c/(k(1 + g))``;
- a pitch error also has a second harmonic, which would read as ellipse: the
  fitted pitch error (P = 5 mm known, as ``--pitch-mm``) is taken out first.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from cnc_tools.analysis.ballbar import CircleTrace, diagnose_circles
from cnc_tools.analysis.ballbar_cyclic import fit_cyclic_error, pitch_error_m
from cnc_tools.analysis.ballbar_reversals import diagnose_reversals
from cnc_tools.analysis.ballbar_trace import SAMPLE_RULE, WHOLE_PROGRAM_RULE, BagTrace, trace_of
from cnc_tools.bagio.record_bag import write_record_bag
from cnc_tools.cli.main import main
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import build_scenario

R_MM = 10.0
FEED_MM_MIN = 300.0
K_PER_S = 60.0
SAMPLE_TIME_S = 0.002
FEED_ARC_DEG = 180.0
START_DEG = 30.0


def _arc_to(angle_deg: float, direction: str) -> dict[str, Any]:
    to = [R_MM * math.cos(math.radians(angle_deg)), R_MM * math.sin(math.radians(angle_deg))]
    return {"arc": {"to_mm": [round(v, 12) for v in to], "center_mm": [0.0, 0.0], "direction": direction}}


def scenario(direction: str, faults: Mapping[str, Any] | None = None,
             coulomb_mm_s: Mapping[str, float] | None = None) -> dict[str, Any]:
    """Feed-in 180°, the turn (two half arcs), feed-out 180°, from START_DEG, in ``direction``."""
    sign = 1.0 if direction == "ccw" else -1.0
    angles = [START_DEG + sign * FEED_ARC_DEG * k for k in range(1, 5)]
    start = [R_MM * math.cos(math.radians(START_DEG)), R_MM * math.sin(math.radians(START_DEG))]
    overrides = {axis: {"coulomb_mm_s": value, "stiction_mm_s": value}
                 for axis, value in (coulomb_mm_s or {}).items()}
    return {"name": f"ballbar_{direction}", "format_version": 2, "sample_time_s": SAMPLE_TIME_S, "settle_s": 0.0,
            "plant": {"model": "paper003", "axes": ["x", "y"], "axis_overrides": overrides,
                      "velocity_loop": {"spindle_rpm": 0, "encoder_pulse_m": 0.0},
                      "faults": dict(faults or {})},
            "servo": {"law": "p", "law_params": {"kp": K_PER_S}, "counts_per_m": 1.0, "output_limit": 1.0,
                      "quantum": 0, "command_unit": "m/s"},
            "limits": {"max_velocity_mm_min": 6000, "max_acceleration_mm_s2": 2000},
            "program": {"axes": ["x", "y"], "start_mm": start, "feed_mm_min": FEED_MM_MIN,
                        "segments": [_arc_to(a, direction) for a in angles]}}


def pair(faults: Mapping[str, Any] | None = None,
         coulomb_mm_s: Mapping[str, float] | None = None) -> list[BagTrace]:
    """The ccw and cw traces (measured turn only) of one machine."""
    return [trace_of(Path(f"engine[{d}]"), run_engine(build_scenario(scenario(d, faults, coulomb_mm_s))))
            for d in ("ccw", "cw")]


R_UM = R_MM * 1e3
V_M_S = FEED_MM_MIN / 60e3
#: 0.5 µm at R as an angle (µrad) or a ratio (ppm): squareness α R/2, scale (sx − sy) R/2.
PER_R = 0.5 / (R_UM / 2.0) * 1e6
PITCH_MM = 5.0


def _within(name: str, measured: float, expected: float, tol_abs: float) -> None:
    assert abs(measured - expected) <= max(0.05 * abs(expected), tol_abs), (name, measured, expected)


def _diagnose(faults: dict[str, Any], coulomb: dict[str, float]) -> dict[str, float]:
    return _read([t.trace for t in pair(faults, coulomb)])


def _read(traces: list[CircleTrace]) -> dict[str, float]:
    """The figures of a ccw/cw pair of traces, the fitted pitch error taken out first."""
    fit = fit_cyclic_error(traces, {"x": PITCH_MM, "y": PITCH_MM})
    explained = [pitch_error_m(t, fit) for t in traces]  # as `cnc-contour circular --pitch-mm` does
    d, r = diagnose_circles(traces, explained), diagnose_reversals(traces, explained_m=explained)
    assert d.servo_mismatch_um is not None and d.squareness_urad is not None
    pitch = fit.amplitude_um
    return {"servo_mismatch_um": d.servo_mismatch_um, "squareness_urad": d.squareness_urad,
            "scale_mismatch_ppm": d.scale_mismatch_ppm, "backlash_x_um": r.backlash_x_um,
            "backlash_y_um": r.backlash_y_um, "cyclic_x_um": pitch["x"], "cyclic_y_um": pitch["y"],
            "lateral_x_um": r.lateral_x_um, "lateral_y_um": r.lateral_y_um}


@pytest.fixture(scope="module")
def fault_free() -> dict[str, RunRecord]:
    """The fault-free machine's ccw and cw runs, made once for the two tests that read them."""
    return {d: run_engine(build_scenario(scenario(d))) for d in ("ccw", "cw")}


def test_the_fault_free_pair_reads_no_fault(fault_free: dict[str, RunRecord]) -> None:
    read = _read([trace_of(Path(f"engine[{d}]"), record).trace for d, record in fault_free.items()])
    for name, value in read.items():
        bound = {"urad": 5.0, "ppm": 5.0}.get(name.rsplit("_", 1)[-1], 0.5)
        assert abs(value) <= bound, (name, value)


AXIS = st.fixed_dictionaries({
    "backlash_um": st.sampled_from([0.0, 3.0, 8.0, 20.0]),
    "scale_ppm": st.sampled_from([0.0, -200.0, 150.0]),
    "drive_gain_pct": st.sampled_from([0.0, -15.0, 20.0]),
    "coulomb_mm_s": st.sampled_from([0.0, 0.3, 1.0]),
    "cyclic_amplitude_um": st.sampled_from([0.0, 0.0, 2.0]),
})


@settings(max_examples=6, deadline=None,  # each example is two engine runs of ~5 s: no shrinking
          phases=(Phase.explicit, Phase.reuse, Phase.generate))
@given(x=AXIS, y=AXIS, squareness_urad=st.sampled_from([0.0, 80.0, -120.0]))
def test_injected_faults_are_diagnosed_at_their_size(x: dict[str, float], y: dict[str, float],
                                                     squareness_urad: float) -> None:
    axes = {"x": x, "y": y}
    faults = {"squareness_urad": squareness_urad,
              "axes": {n: {**{k: v for k, v in a.items() if k != "coulomb_mm_s"}, "cyclic_pitch_mm": PITCH_MM}
                       for n, a in axes.items()}}
    read = _diagnose(faults, {n: a["coulomb_mm_s"] for n, a in axes.items() if a["coulomb_mm_s"]})
    k = {n: K_PER_S * (1.0 + 0.01 * a["drive_gain_pct"]) for n, a in axes.items()}
    for n, a in axes.items():
        lost_um = a["backlash_um"] + 2.0 * a["coulomb_mm_s"] / k[n] * 1e3  # the drive gain scales u, not c
        _within(f"backlash_{n}_um", read[f"backlash_{n}_um"], lost_um, 0.5)
        _within(f"cyclic_{n}_um", read[f"cyclic_{n}_um"], a["cyclic_amplitude_um"], 0.5)
    _within("servo_mismatch_um", read["servo_mismatch_um"], 0.5 * V_M_S * (1 / k["x"] - 1 / k["y"]) * 1e6, 0.5)
    _within("squareness_urad", read["squareness_urad"], squareness_urad, PER_R)
    _within("scale_mismatch_ppm", read["scale_mismatch_ppm"], x["scale_ppm"] - y["scale_ppm"], PER_R)


def test_the_command_says_which_samples_it_used(fault_free: dict[str, RunRecord], tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """A standard pair: the measured turn after 180° of feed-in arc; one turn from rest: flagged, with a warning."""
    bags = [str(write_record_bag(record, tmp_path / d)) for d, record in fault_free.items()]
    assert main(["circular", *bags]) == 0
    out = capsys.readouterr().out
    assert "samples ccw: " + SAMPLE_RULE + " (feed-in and feed-out arcs 180.0°)" in out
    assert "figures: spikes: the residual inside the reversal windows" in out and "warning:" not in out
    raw = scenario("ccw")
    raw["program"]["segments"] = raw["program"]["segments"][:2]  # one turn from rest: no feed arcs
    record = run_engine(build_scenario(raw))
    trace = trace_of(Path("one_turn"), record)
    assert not trace.standard and trace.rule == WHOLE_PROGRAM_RULE and trace.feed_in_deg == 0.0
    assert main(["circular", str(write_record_bag(record, tmp_path / "one_turn"))]) == 0
    out = capsys.readouterr().out
    assert "samples ccw: " + WHOLE_PROGRAM_RULE in out and "not a standard circular test" in out
