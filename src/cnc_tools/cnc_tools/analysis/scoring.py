"""Score a recorded run: exact contour error, tracking error, circular test.

The contour error of a sample is the distance from its recorded position to the
nearest point of the recorded program (``Program.contour_distance``), never an
estimator's value. Scored samples: every ``joint_states`` sample from the first
``reference`` stamp to the end of the run (all samples when the bag holds no
reference); the count of samples left out before the first reference is part
of every output. Tracking error per axis is reference - position at the stamps
both topics share. Samples with a non-finite position (or reference) are left
out and counted; the run's verdict (:mod:`cnc_tools.analysis.verdict`), when
given, names them and is part of every output.
"""
from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import cast

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.core.units import M_PER_BLU_PAPER000, M_PER_MM, M_PER_UM
from cnc_contour_control.motion.geometry import ArcSegment, Program
from cnc_tools.analysis.circular import CircularTest, analyse_circle, circle_of
from cnc_tools.analysis.force import ForceFigures, force_figures
from cnc_tools.analysis.metrics import Metric, evaluate, get_metrics, length_units, trapezoid_weights_s
from cnc_tools.analysis.reference_deviation import ReferenceDeviation, reference_deviation
from cnc_tools.analysis.verdict import Verdict
from cnc_tools.run_record import BagIntegrity, RecordedRun

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Metrics of the per-axis tracking error (from the registry).
TRACKING_METRICS: tuple[str, ...] = ("max", "rms")
#: Fewest samples for a circular test.
MIN_CIRCLE_SAMPLES = 8


@dataclass(frozen=True, eq=False)
class ContourErrorSeries:
    """Exact contour error of the scored samples.

    ``stamp_ns`` (N,) ns; ``position_m`` (N, n_axes) m; ``error_m`` (N,) distance to the
    contour, m (>= 0); ``segment_index`` (N,) nearest segment; ``path_length_m`` (N,) arc
    length along the program of the nearest point, m; ``weight_s`` (N,) trapezoid weights, s.
    """

    stamp_ns: IntArray
    position_m: FloatArray
    error_m: FloatArray
    segment_index: IntArray
    path_length_m: FloatArray
    weight_s: FloatArray

    @property
    def time_s(self) -> FloatArray:
        """Sample times, s (simulation clock)."""
        return self.stamp_ns * np.float64(1e-9)


@dataclass(frozen=True)
class ScoredWindow:
    """Which samples were scored, and why the others were not."""

    rule: str
    n_recorded: int
    n_scored: int
    n_before_start: int
    start_s: float
    end_s: float
    n_non_finite: int = 0

    def describe(self) -> str:
        """One sentence for people."""
        left_out = f"; {self.n_non_finite} samples with a non-finite position not scored" if self.n_non_finite else ""
        return (f"scored {self.n_scored} of {self.n_recorded} joint_states samples, t = {self.start_s:.6g} .. "
                f"{self.end_s:.6g} s ({self.rule}; {self.n_before_start} samples before it not scored{left_out})")


@dataclass(frozen=True)
class ErrorStats:
    """Metric values (SI: m, m²·s) of one error signal over ``n_samples`` samples."""

    label: str
    n_samples: int
    values_si: dict[str, float]


def _segment_label(index: int, program: Program) -> str:
    seg = program.segments[index]
    kind = ("arc cw" if seg.clockwise else "arc ccw") if isinstance(seg, ArcSegment) else "line"
    return f"{index} {kind}"


def _scored_window(run: RecordedRun) -> tuple[NDArray[np.bool_], ScoredWindow]:
    stamps = run.joint_states.stamp_ns
    if run.reference is not None and run.reference.stamp_ns.size:
        start_ns, rule = int(run.reference.stamp_ns[0]), "from the first reference to the end of the run"
    else:
        start_ns, rule = int(stamps[0]), "all samples: the bag holds no reference"
    after_start = stamps >= start_ns
    finite = np.isfinite(run.joint_states.position_m).all(axis=1)
    mask = after_start & finite
    kept = stamps[mask]
    window = ScoredWindow(rule, int(stamps.size), int(mask.sum()), int((~after_start).sum()),
                          float(kept[0] * 1e-9) if kept.size else math.nan,
                          float(kept[-1] * 1e-9) if kept.size else math.nan, int((after_start & ~finite).sum()))
    return mask, window


def _path_length_m(program: Program, points: FloatArray, segment_index: IntArray) -> FloatArray:
    out = np.zeros(segment_index.size)
    for index in np.unique(segment_index):
        rows = segment_index == index
        _, s_m = program.segments[index].nearest(points[rows])
        out[rows] = program.segment_start_m[index] + s_m
    return out


def contour_error_series(run: RecordedRun) -> tuple[ContourErrorSeries, ScoredWindow]:
    """Exact contour error at every scored sample of ``run`` and the window description."""
    mask, window = _scored_window(run)
    stamps = run.joint_states.stamp_ns[mask]
    points = run.joint_states.position_m[mask]
    error, index = run.program.contour_distance(points)
    index = index.astype(np.int64)
    series = ContourErrorSeries(stamps, points, error, index, _path_length_m(run.program, points, index),
                                trapezoid_weights_s(stamps * np.float64(1e-9)))
    return series, window


def tracking_errors(run: RecordedRun) -> tuple[IntArray, FloatArray]:
    """Reference - position at the stamps both topics hold: stamps (M,) ns and errors (M, n_axes) m."""
    if run.reference is None:
        return np.zeros(0, np.int64), np.zeros((0, len(run.axis_names)))
    stamps, js_rows, ref_rows = np.intersect1d(run.joint_states.stamp_ns, run.reference.stamp_ns,
                                               assume_unique=False, return_indices=True)
    error = run.reference.position_m[ref_rows] - run.joint_states.position_m[js_rows]
    finite = np.isfinite(error).all(axis=1)
    return stamps[finite].astype(np.int64), error[finite]


def _tracking_stats(run: RecordedRun) -> tuple[tuple[ErrorStats, ...], str]:
    stamps, error = tracking_errors(run)
    metrics = get_metrics(TRACKING_METRICS)
    weight = trapezoid_weights_s(stamps * np.float64(1e-9))
    stats = tuple(ErrorStats(axis, int(stamps.size), evaluate(metrics, error[:, k], weight))
                  for k, axis in enumerate(run.axis_names))
    n_ref = 0 if run.reference is None else run.reference.stamp_ns.size
    note = (f"reference - position at {stamps.size} shared stamps "
            f"({run.joint_states.stamp_ns.size} joint_states, {n_ref} references)")
    return stats, note


def _circular(run: RecordedRun, series: ContourErrorSeries, window_deg: float) -> CircularTest | None:
    circle = circle_of(run.program)
    if circle is None or series.stamp_ns.size < MIN_CIRCLE_SAMPLES:
        return None
    velocity = run.joint_states.velocity_m_s[_scored_window(run)[0]]
    if run.reference is not None:
        rows = np.searchsorted(run.reference.stamp_ns, series.stamp_ns)
        shared = (rows < run.reference.stamp_ns.size) & \
            (run.reference.stamp_ns[np.minimum(rows, run.reference.stamp_ns.size - 1)] == series.stamp_ns)
        if shared.all():
            velocity = run.reference.velocity_m_s[rows]
    return analyse_circle(circle, run.axis_names, series.stamp_ns, series.position_m, velocity,
                          window_deg=window_deg)


@dataclass(frozen=True, eq=False)
class Score:
    """The score of one run; ``to_table``, ``to_json`` and ``to_csv`` render it (µm and BLU)."""

    run_name: str
    program_name: str
    metrics: tuple[Metric, ...]
    blu_m: float
    window: ScoredWindow
    contour: ErrorStats
    segments: tuple[ErrorStats, ...]
    tracking: tuple[ErrorStats, ...]
    tracking_note: str
    circular: CircularTest | None
    integrity: BagIntegrity
    series: ContourErrorSeries = field(repr=False)
    verdict: Verdict | None = None
    force: ForceFigures | None = None
    #: The reference's own deviation from the programmed path (corner blends) beside the path tolerance.
    deviation: ReferenceDeviation | None = None

    def to_dict(self) -> dict[str, object]:
        """Plain data: every length in µm and BLU, keys carry their unit."""
        units = length_units(self.blu_m)
        tracking_metrics = get_metrics(TRACKING_METRICS)
        return {
            "run": self.run_name, "program": self.program_name, "blu_um": self.blu_m / M_PER_UM,
            "verdict": None if self.verdict is None else self.verdict.to_dict(),
            "scored_samples": {**asdict(self.window), "description": self.window.describe()},
            "integrity": _integrity_dict(self.integrity),
            "contour_error": _stats_dict(self.contour, self.metrics, units),
            "segments": [_stats_dict(stats, self.metrics, units) for stats in self.segments],
            "tracking_error": {s.label: _stats_dict(s, tracking_metrics, units) for s in self.tracking},
            "tracking_error_note": self.tracking_note,
            "circular_test": None if self.circular is None else _circular_dict(self.circular, units),
            "cutting_force": None if self.force is None else self.force.to_dict(),
            "reference_deviation": None if self.deviation is None else self.deviation.to_dict(),
        }

    def to_json(self, indent: int | None = 2) -> str:
        """JSON of ``to_dict`` (NaN written as null)."""
        return json.dumps(_nan_to_none(self.to_dict()), indent=indent, ensure_ascii=False)

    def to_csv(self) -> str:
        """Long-format CSV: run, scope, item, metric, value, unit (one row per value)."""
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(("run", "scope", "item", "n_samples", "metric", "value", "unit"))
        writer.writerows(_csv_rows(self))
        return buffer.getvalue()

    def to_table(self) -> str:
        """Aligned table for a terminal."""
        return "\n".join(_table_lines(self))


def score_run(run: RecordedRun, metrics: Sequence[str] | None = None, *, blu_m: float = M_PER_BLU_PAPER000,
              window_deg: float = 10.0, verdict: Verdict | None = None,
              force_reference_n: float | None = None) -> Score:
    """Score one recorded run.

    Parameters
    ----------
    run
        The recorded run (``bag.read_bag``).
    metrics
        Metric names from ``metrics.METRICS``; default ``metrics.DEFAULT_METRICS``.
    blu_m
        The basic length unit for BLU columns, m (paper 000: 10 µm).
    window_deg
        Half-width of the arc searched around each velocity reversal (circle programs), degrees.
    verdict
        The run's verdict (:func:`cnc_tools.analysis.verdict.judge`), shown in every output.
    force_reference_n
        The force regulator's reference [N]: a run that cut is scored against it
        (:mod:`cnc_tools.analysis.force`; without it, peaks, means and ripple only).
    """
    chosen = get_metrics(metrics)
    length_units(blu_m)
    series, window = contour_error_series(run)
    segments = tuple(
        ErrorStats(_segment_label(i, run.program), int(np.sum(series.segment_index == i)),
                   evaluate(chosen, series.error_m[series.segment_index == i],
                            series.weight_s[series.segment_index == i]))
        for i in range(len(run.program.segments)))
    tracking, tracking_note = _tracking_stats(run)
    return Score(run.name, run.program.name, chosen, blu_m, window,
                 ErrorStats("run", int(series.error_m.size), evaluate(chosen, series.error_m, series.weight_s)),
                 segments, tracking, tracking_note, _circular(run, series, window_deg), run.integrity, series,
                 verdict, force_figures(run, force_reference_n), reference_deviation(run))


# =========================================================================== rendering
def _nan_to_none(value: object) -> object:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _nan_to_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_nan_to_none(v) for v in value]
    return value


def _stats_dict(stats: ErrorStats, metrics: Sequence[Metric], units: Mapping[str, float]) -> dict[str, object]:
    out: dict[str, object] = {"item": stats.label, "n_samples": stats.n_samples}
    for metric in metrics:
        for unit, m_per_unit in units.items():
            out[f"{metric.name}_{metric.unit_key(unit)}"] = metric.convert(stats.values_si[metric.name], m_per_unit)
    return out


def _lengths(name: str, value_m: float, units: Mapping[str, float]) -> dict[str, float]:
    return {f"{name}_{unit}": value_m / m_per_unit for unit, m_per_unit in units.items()}


def _integrity_dict(integrity: BagIntegrity) -> dict[str, object]:
    return {"complete": integrity.complete, "method": integrity.method, "found": dict(integrity.found),
            "expected": None if integrity.expected is None else dict(integrity.expected),
            "expected_source": integrity.expected_source, "lost": integrity.lost,
            "problems": list(integrity.problems), "description": integrity.describe()}


#: Circular-test lengths reported, attribute -> output name.
_CIRCULAR_LENGTHS = {
    "circular_deviation_m": "circular_deviation_G", "circular_deviation_nominal_m": "circular_deviation_nominal",
    "radial_deviation_min_m": "radial_deviation_min", "radial_deviation_max_m": "radial_deviation_max",
    "mean_radius_error_m": "mean_radius_error",
}


def _circular_dict(test: CircularTest, units: Mapping[str, float]) -> dict[str, object]:
    out: dict[str, object] = {
        "axes": list(test.axis_names), "n_samples": test.n_samples,
        "radius_mm": test.circle.radius_m / M_PER_MM, "center_mm": [c / M_PER_MM for c in test.circle.center_m],
        "lsq_center_offset_um": [(f - c) / M_PER_UM for f, c in zip(test.lsq_center_m, test.circle.center_m)],
        "lsq_radius_error_um": (test.lsq_radius_m - test.circle.radius_m) / M_PER_UM,
        "reversal_window_deg": test.window_deg,
    }
    for attribute, name in _CIRCULAR_LENGTHS.items():
        out.update(_lengths(name, getattr(test, attribute), units))
    out["reversals"] = [
        {"axis": r.axis_name, "time_s": r.stamp_ns * 1e-9, "angle_deg": r.angle_deg,
         **_lengths("peak_radial_deviation", r.peak_radial_deviation_m, units), **_lengths("spike", r.spike_m, units)}
        for r in test.reversals]
    return out


def _csv_groups(data: Mapping[str, object]) -> list[tuple[str, list[dict[str, object]]]]:
    """(scope, items) of the score's plain data; every item has ``item``, ``n_samples`` and unit-suffixed values."""
    groups = [("contour", [data["contour_error"]]), ("segment", data["segments"]),
              ("tracking", list(cast(Mapping[str, object], data["tracking_error"]).values()))]
    deviation = data["reference_deviation"]
    if isinstance(deviation, dict):
        groups.append(("reference_deviation", [{"item": "reference", "n_samples": deviation["n_samples"],
                                                **{k: v for k, v in deviation.items() if k.endswith("_um")}}]))
    circular = data["circular_test"]
    if isinstance(circular, dict):
        lengths = {k: v for k, v in circular.items() if k.endswith(("_um", "_blu")) and isinstance(v, float)}
        groups.append(("circular", [{"item": "circle", "n_samples": circular["n_samples"], **lengths}]))
        groups.append(("reversal", [
            {"item": f"{r['axis']} at {r['angle_deg']:.1f} deg", "n_samples": 1,
             **{k: v for k, v in r.items() if k.startswith(("peak_", "spike_"))}} for r in circular["reversals"]]))
    return groups  # type: ignore[return-value]  # data holds the score's plain dicts


def _csv_rows(score: Score) -> Iterator[tuple[object, ...]]:
    for scope, items in _csv_groups(score.to_dict()):
        for stats in items:
            for key, value in stats.items():
                if key not in ("item", "n_samples"):
                    metric, unit = _split_key(key)
                    cell = "" if isinstance(value, float) and not math.isfinite(value) else value
                    yield score.run_name, scope, stats["item"], stats["n_samples"], metric, cell, unit


def _split_key(key: str) -> tuple[str, str]:
    for unit in ("um2_s", "blu2_s", "um", "blu"):
        if key.endswith("_" + unit):
            return key[:-len(unit) - 1], unit
    return key, ""


def _fmt(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{value:.5g}"


def _render(header: Sequence[Sequence[str]], rows: Sequence[Sequence[str]]) -> list[str]:
    widths = [max(len(r[i]) for r in (*header, *rows)) for i in range(len(header[0]))]
    def line(cells: Sequence[str]) -> str:
        return "  " + "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))
    return [line(h) for h in header] + [line(r) for r in rows]


def _stats_rows(stats: Sequence[ErrorStats], metrics: Sequence[Metric], unit: str, m_per_unit: float,
                suffix: str = "") -> list[list[str]]:
    return [[s.label + suffix, str(s.n_samples),
             *(_fmt(m.convert(s.values_si[m.name], m_per_unit)) for m in metrics)] for s in stats]


def _error_table(title: str, stats: Sequence[ErrorStats], extra: Sequence[ErrorStats], metrics: Sequence[Metric],
                 units: Mapping[str, float]) -> list[str]:
    header = [[title, "n", *(m.name for m in metrics)], ["", "", *(m.unit_label("um") for m in metrics)]]
    rows = _stats_rows(stats, metrics, "um", units["um"])
    rows += _stats_rows(stats, list(metrics), "blu", units["blu"], " [BLU]")
    rows += _stats_rows(extra, metrics, "um", units["um"])
    return _render(header, rows)


def _circular_lines(test: CircularTest, units: Mapping[str, float]) -> list[str]:
    um, blu = units["um"], units["blu"]
    rows = [[name.replace("_", " "), _fmt(getattr(test, attr) / um), _fmt(getattr(test, attr) / blu)]
            for attr, name in _CIRCULAR_LENGTHS.items()]
    rows += [[f"reversal {r.axis_name} at {r.angle_deg:.1f}° (t={r.stamp_ns * 1e-9:.4g} s): spike",
              _fmt(r.spike_m / um), _fmt(r.spike_m / blu)] for r in test.reversals]
    title = (f"circular test (ISO 230-4), R = {test.circle.radius_m / M_PER_MM:.6g} mm, plane "
             f"{'/'.join(test.axis_names)}, {test.n_samples} samples, reversal window ±{test.window_deg:g}°")
    return [title, *_render([["quantity", "µm", "BLU"]], rows)]


def _table_lines(score: Score) -> Iterator[str]:
    units = length_units(score.blu_m)
    yield f"run {score.run_name}: program {score.program_name!r}, BLU = {score.blu_m / M_PER_UM:g} µm"
    yield f"{'record' if score.integrity.method == 'engine' else 'bag'}: {score.integrity.describe()}"
    if score.verdict is not None:
        yield f"verdict: {score.verdict.describe()}"
    yield f"samples: {score.window.describe()}"
    yield "contour error = distance from the recorded position to the recorded program (exact, not the estimator)"
    yield from _error_table("contour error", [score.contour], score.segments, score.metrics, units)
    if score.deviation is not None:
        yield from score.deviation.lines()
    yield f"tracking error: {score.tracking_note}"
    tracking = get_metrics(TRACKING_METRICS)
    yield from _render([["axis", "n", *(f"{m.name} µm" for m in tracking), *(f"{m.name} BLU" for m in tracking)]],
                       [[s.label, str(s.n_samples), *(_fmt(m.convert(s.values_si[m.name], units[u]))
                                                      for u in ("um", "blu") for m in tracking)]
                        for s in score.tracking])
    if score.circular is not None:
        yield from _circular_lines(score.circular, units)
    if score.force is not None:
        yield from score.force.lines()
