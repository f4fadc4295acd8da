"""``cnc-contour circular BAG [BAG] [--json FILE] [--plot FILE.png] [--pitch-mm AXIS=MM]``: ballbar diagnoses
of a recorded circle (and its reverse).

Each bag's program must be one circle; its trace (direction, feed, the samples on
the arc) is taken by :func:`cnc_tools.analysis.ballbar_trace.trace_of`, which the
tuner's simulated circular test uses too. Two bags must be a cw and a ccw run of the same
circle; one bag gives the diagnoses that need one direction, the rest are
listed as skipped. See ``docs/circular_test.md``.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import BagError, CncError
from cnc_tools.analysis.ballbar import (
    CYCLIC_HARMONICS,
    SAME_CIRCLE_TOLERANCE_M,
    BallbarDiagnosis,
    diagnose_circles,
)
from cnc_tools.analysis.ballbar_cyclic import PLANE_AXES, CyclicFit, fit_cyclic_error, pitch_error_m
from cnc_tools.analysis.ballbar_radius import measured_radius_loss_um, model_from_scenario, predict_radius_loss
from cnc_tools.analysis.ballbar_reversals import FLANK_DEG, ReversalDiagnosis, diagnose_reversals, write_polar_plot
from cnc_tools.analysis.ballbar_trace import (  # noqa: F401 - measured_positions, arc_samples: re-exported
    SAMPLE_RULE,
    BagTrace,
    arc_samples,
    measured_positions,
    trace_of,
)


@dataclass(frozen=True)
class Row:
    """One line of the table: a field of :class:`BallbarDiagnosis`, its unit and how it is computed."""

    field: str
    unit: str
    how: str


#: The table's rows, in order (a registry: add a diagnosis here and it is printed and documented).
ROWS: tuple[Row, ...] = (
    Row("circularity_ls_um", "µm", "max - min radius about the least-squares circle (largest over the traces)"),
    Row("circularity_mz_um", "µm", "width of the thinnest annulus holding every point (minimum zone)"),
    Row("radial_deviation_max_um", "µm", "largest |p - c| - R about the programmed centre"),
    Row("radial_deviation_min_um", "µm", "smallest |p - c| - R about the programmed centre"),
    Row("center_offset_x_um", "µm", "least-squares centre - programmed centre, x (mean of the traces)"),
    Row("center_offset_y_um", "µm", "least-squares centre - programmed centre, y (mean of the traces)"),
    Row("servo_mismatch_um", "µm", "(B2_ccw - B2_cw)/2: the ±45° ellipse that flips with direction"),
    Row("gain_difference_s", "s", "1/k_x - 1/k_y = 2 servo_mismatch / mean feed (Eq. 8, first order)"),
    Row("squareness_urad", "µrad", "(B2_ccw + B2_cw)/R_d (R_d the drawn radius): the ±45° ellipse common to both "
        "directions"),
    Row("scale_mismatch_um", "µm", "mean A2: the 0°/90° ellipse common to the traces"),
    Row("scale_mismatch_ppm", "ppm", "sx - sy = 2 mean A2 / R_d"),
)
#: Rows of each trace: a field of :class:`cnc_tools.analysis.ballbar.TraceDiagnosis`.
TRACE_ROWS: tuple[Row, ...] = (
    Row("circularity_ls_um", "µm", "max - min radius about this trace's least-squares circle"),
    Row("ellipse_45_um", "µm", "B2, the sin 2θ term of the radius deviation (±45° ellipse)"),
    Row("ellipse_0_um", "µm", "A2, the cos 2θ term of the radius deviation (0°/90° ellipse)"),
)
CYCLIC_HOW = "amplitude of harmonic {k} of the traces' mean radius deviation"
#: Rows of the reversals: a field of :class:`cnc_tools.analysis.ballbar_reversals.ReversalDiagnosis`.
REVERSAL_ROWS: tuple[Row, ...] = (
    Row("spike_x_um", "µm", "largest reversal spike of x (0°/180°) over the traces, signed"),
    Row("spike_y_um", "µm", "largest reversal spike of y (90°/270°) over the traces, signed"),
    Row("backlash_x_um", "µm", "x step b_x: half-circle shift of the trace along x against the motion, fitted "
        "beside eccentricity and ellipses outside the reversal windows"),
    Row("backlash_y_um", "µm", "y step b_y: half-circle shift of the trace along y against the motion, fitted "
        "beside eccentricity and ellipses outside the reversal windows"),
    Row("lateral_x_um", "µm", "mean shift along y at the x reversals (flank slope change per rad) x motion sign"),
    Row("lateral_y_um", "µm", "mean shift along x at the y reversals (flank slope change per rad) x motion sign"),
)
REVERSAL_HOW = {
    "spike": "largest residual (deviation - fitted model) at the {axis} reversal at {angle:g}° ({motion}), "
             "from {before:g}° before to {after:g}° after it",
    "step": "step at the {axis} reversal at {angle:g}° ({motion}): b_{axis} + the step shape in the residual "
            "on the {flank:g}° flanks outside the window",
}
#: Which samples each group of figures uses (printed under the traces' sample rule).
FIGURE_SAMPLES = (
    "figures: circularity, radial deviation, centre offset: every sample of the measured turn",
    "figures: ellipses (servo mismatch, squareness, scale), harmonics, backlash: the measured turn outside the "
    "reversal windows ({before:g}° before to {after:g}° after each reversal in time), backlash steps taken out",
    "figures: spikes: the residual inside the reversal windows",
)


def configure(parser: argparse.ArgumentParser) -> None:
    """Options of ``cnc-contour circular``."""
    parser.add_argument("bags", nargs="+", type=Path, help="one or two bags: a cw and a ccw run of one circle")
    parser.add_argument("--json", type=Path, help="also write the diagnosis to this JSON file")
    parser.add_argument("--plot", type=Path, help="also write the annotated polar plot to this PNG file")
    parser.add_argument("--pitch-mm", action="append", default=[], metavar="AXIS=MM",
                        help="fit the cyclic (lead-screw pitch) error of a plane axis (x: the plane's first, "
                             "y: its second) of this pitch, mm; repeat for the other axis")


def pitches(words: Sequence[str]) -> dict[str, float]:
    """``["x=5", "y=4"]`` -> ``{"x": 5.0, "y": 4.0}``; CncError names a bad word."""
    out: dict[str, float] = {}
    for word in words:
        axis, _, value = word.partition("=")
        try:
            out[axis.strip()] = float(value)
        except ValueError as err:
            raise CncError(f"--pitch-mm must be AXIS=MM with AXIS one of {sorted(PLANE_AXES)}, got {word!r}") from err
    return out


def cyclic_rows(fit: CyclicFit) -> list[tuple[str, float | None, str, str]]:
    """``(quantity, value, unit, how)`` of the pitch-error fit, one row per axis."""
    return [(f"cyclic_pitch_{axis}_um", amplitude, "µm",
             f"amplitude of A sin(2π q_{axis}/P) fitted with P = {fit.pitch_mm[axis]:g} mm (least squares, "
             f"harmonics 0..2 per trace beside it)") for axis, amplitude in fit.amplitude_um.items()]


def check_pair(traces: Sequence[BagTrace]) -> None:
    """Raise CncError naming the bags unless one trace, or two of one circle in opposite directions."""
    if len(traces) != 2:
        return
    first, second = traces
    if first.trace.direction == second.trace.direction:
        raise CncError(f"{first.bag}, {second.bag}: both run {first.trace.direction}; "
                       "give a cw and a ccw run of the same circle")
    gap_m = math.dist(first.circle.center_m, second.circle.center_m)
    radius_gap_m = abs(first.circle.radius_m - second.circle.radius_m)
    if gap_m > SAME_CIRCLE_TOLERANCE_M or radius_gap_m > SAME_CIRCLE_TOLERANCE_M \
            or first.circle.plane != second.circle.plane:
        raise CncError(f"{second.bag}: programs a different circle than {first.bag}: centre "
                       f"{second.circle.center_m} m, radius {second.circle.radius_m} m, plane {second.circle.plane} "
                       f"vs centre {first.circle.center_m} m, radius {first.circle.radius_m} m, "
                       f"plane {first.circle.plane}")


def read_traces(bags: Sequence[Path]) -> list[BagTrace]:
    """Read and check the bags' circle traces; CncError names the bag and the problem."""
    from cnc_tools.bagio.bag import read_bag  # rosbags: loaded only when a bag is read

    if not 1 <= len(bags) <= 2:
        raise CncError(f"circular takes 1 or 2 bags (a cw and a ccw run), got {len(bags)}")
    traces = []
    for bag in bags:
        try:
            record = read_bag(bag, commands=False)
        except BagError as err:
            message = str(err)
            raise CncError(message if message.startswith(str(bag)) else f"{bag}: {message}") from err
        traces.append(trace_of(bag, record))
    check_pair(traces)
    return traces


def reversal_rows(reversals: ReversalDiagnosis) -> list[tuple[str, float | None, str, str]]:
    """``(quantity, value, unit, how)`` of the per-axis summary and of every reversal."""
    rows: list[tuple[str, float | None, str, str]] = [
        (row.field, getattr(reversals, row.field), row.unit, row.how) for row in REVERSAL_ROWS]
    for r in reversals.reversals:
        for what, value in (("spike", r.spike_um), ("step", r.step_um)):
            how = REVERSAL_HOW[what].format(axis=r.axis, angle=r.angle_deg, motion=r.motion,
                                            before=reversals.before_deg, after=reversals.after_deg, flank=FLANK_DEG)
            rows.append((f"{r.direction}.{r.axis}{r.angle_deg:g}.{what}_um", value, "µm", how))
    return rows


RADIUS_HOW = {
    "radius_loss_measured_um": "mean of R - |p - c| over the trace",
    "radius_loss_predicted_um": "R (1 - |G_servo(jω)| |G_ip(jω)|), ω = F/R: servo lag and accel/decel together",
    "servo_lag_um": "Eq. 12 as the P loop's lag: R (1 - |(ff s + k)/(s + k)|) at s = jω (scenario's k, ff1)",
    "accel_decel_um": "R (1 - |G_ip(jω)|): the accel/decel filter after interpolation (scenario's T_ip, kind)",
    "accel_decel_eq13_um": "Eq. 13: T_ip² F²/(2R) exponential, /(24R) linear",
}


def radius_rows(traces: Sequence[BagTrace]) -> tuple[list[tuple[str, float | None, str, str]], list[str]]:
    """Measured and predicted radius reduction per trace (Eqs. 12-13), from the ``scenario.yaml`` beside each bag."""
    from cnc_contour_control.core.config import load_yaml  # a user's scenario: YAML 1.2 floats (1e-3) are numbers

    rows: list[tuple[str, float | None, str, str]] = []
    skipped: list[str] = []
    for t in traces:
        d = t.trace.direction
        rows.append((f"{d}.radius_loss_measured_um", measured_radius_loss_um(t.trace), "µm",
                     RADIUS_HOW["radius_loss_measured_um"]))
        scenario_file = Path(t.bag).parent / "scenario.yaml"
        if not scenario_file.is_file() or t.trace.feed_m_s is None:
            skipped.append(f"{d}.radius_loss_predicted_um: no scenario.yaml beside {t.bag}")
            continue
        model = model_from_scenario(load_yaml(scenario_file.read_text()) or {})
        loss = predict_radius_loss(model, t.trace.feed_m_s, t.trace.radius_m)
        for name in ("radius_loss_predicted_um", "servo_lag_um", "accel_decel_um", "accel_decel_eq13_um"):
            value = getattr(loss, "total_um" if name == "radius_loss_predicted_um" else name)
            rows.append((f"{d}.{name}", value, "µm", RADIUS_HOW[name]))
        skipped += [f"{d}.{loss.skipped}"] if loss.skipped else []
    return rows, skipped


def table_rows(diagnosis: BallbarDiagnosis, reversals: ReversalDiagnosis | None = None,
               cyclic: CyclicFit | None = None) -> list[tuple[str, float | None, str, str]]:
    """``(quantity, value, unit, how)`` for every row; ``None`` where a diagnosis was skipped."""
    rows: list[tuple[str, float | None, str, str]] = [
        (row.field, getattr(diagnosis, row.field), row.unit, row.how) for row in ROWS]
    rows += [(f"cyclic_error_h{k}_um", value, "µm", CYCLIC_HOW.format(k=k))
             for k, value in zip(CYCLIC_HARMONICS, diagnosis.cyclic_error_um)]
    for trace in diagnosis.traces:
        rows += [(f"{trace.direction}.{row.field}", getattr(trace, row.field), row.unit, row.how) for row in TRACE_ROWS]
    rows += cyclic_rows(cyclic) if cyclic is not None else []
    return rows + (reversal_rows(reversals) if reversals is not None else [])


def sample_lines(traces: Sequence[BagTrace], reversals: ReversalDiagnosis | None,
                 cyclic: CyclicFit | None = None) -> list[str]:
    """Which samples each trace and each group of figures uses; a warning for a non-standard test."""
    lines = [f"samples {t.trace.direction}: {t.rule}" + (f" (feed-in and feed-out arcs {t.feed_in_deg:.1f}°)"
                                                          if t.standard else "") for t in traces]
    if reversals is not None:
        lines += [line.format(before=reversals.before_deg, after=reversals.after_deg) for line in FIGURE_SAMPLES]
    if cyclic is not None:
        lines.append("figures: the fitted pitch error is taken out before the ellipses, harmonics, backlash and "
                     "spikes are fitted")
    lines += [f"warning: {t.bag}: not a standard circular test: the program has no feed-in and feed-out arcs, so "
              "the start and end transients are diagnosed as if they were the machine (docs/circular_test.md)"
              for t in traces if not t.standard]
    return lines


def to_table(traces: Sequence[BagTrace], diagnosis: BallbarDiagnosis,
             reversals: ReversalDiagnosis | None = None, cyclic: CyclicFit | None = None) -> str:
    """The printed report: the traces used, the diagnosis table, the skipped diagnoses."""
    lines = [f"trace {t.trace.direction}: {t.bag} ({t.n_samples} samples, "
             f"feed {t.trace.feed_m_s * 60e3:.1f} mm/min)"  # type: ignore[operator]  # a bag's trace has its feed
             for t in traces]
    lines += sample_lines(traces, reversals, cyclic)
    lines.append(f"{'quantity':<28} {'value':>12} {'unit':<5} how")
    radius, radius_skipped = radius_rows(traces)
    for name, value, unit, how in table_rows(diagnosis, reversals, cyclic) + radius:
        shown = "skipped" if value is None else f"{value:.6g}"
        lines.append(f"{name:<28} {shown:>12} {unit:<5} {how}")
    lines += [f"skipped: {reason}" for reason in (*diagnosis.skipped, *radius_skipped)]
    return "\n".join(lines)


def to_json(traces: Sequence[BagTrace], diagnosis: BallbarDiagnosis,
            reversals: ReversalDiagnosis | None = None, cyclic: CyclicFit | None = None) -> dict[str, Any]:
    """The diagnosis as JSON: every field of :class:`BallbarDiagnosis` (and of the reversals and the pitch-error
    fit), the traces and the sample rule."""
    extra = {} if reversals is None else {"reversals": dataclasses.asdict(reversals)}
    if cyclic is not None:
        extra["cyclic_pitch"] = dataclasses.asdict(cyclic)
    return {**extra, "samples": sample_lines(traces, reversals, cyclic),
            "traces": [{"bag": str(t.bag), "direction": t.trace.direction, "n_samples": t.n_samples,
                        "samples": t.rule, "feed_in_deg": t.feed_in_deg,
                        "feed_m_s": t.trace.feed_m_s, "center_m": list(t.circle.center_m),
                        "radius_m": t.circle.radius_m} for t in traces],
            "diagnosis": dataclasses.asdict(diagnosis),
            "rows": [{"quantity": n, "value": v, "unit": u, "how": h}
                     for n, v, u, h in table_rows(diagnosis, reversals, cyclic) + radius_rows(traces)[0]]}


def circular(args: argparse.Namespace) -> int:
    """Diagnose the recorded circle(s); a bad bag is one ``error:`` line and exit code 1."""
    try:
        traces = read_traces(args.bags)
        pitch_mm = pitches(args.pitch_mm)
        cyclic = fit_cyclic_error([t.trace for t in traces], pitch_mm) if pitch_mm else None
        explained = None if cyclic is None else [pitch_error_m(t.trace, cyclic) for t in traces]
        diagnosis = diagnose_circles([t.trace for t in traces], explained)
        reversals = diagnose_reversals([t.trace for t in traces], explained_m=explained)
    except CncError as err:
        print(f"cnc-contour circular: error: {err}", file=sys.stderr)
        return 1
    print(to_table(traces, diagnosis, reversals, cyclic))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        written = to_json(traces, diagnosis, reversals, cyclic)
        args.json.write_text(json.dumps(written, indent=2, ensure_ascii=False) + "\n")
        print(f"json: {args.json}")
    if args.plot:  # matplotlib is imported by write_polar_plot, on use
        print(f"plot: {write_polar_plot([t.trace for t in traces], diagnosis, reversals, args.plot)}")
    return 0
