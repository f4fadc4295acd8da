"""Bench ``paper004-milling``: the force regulator on a 2-axis milling contour, contour error beside force.

Issue 12's "beyond the paper": regulating the cutting force must not cost
contour accuracy. ``scenarios/paper004_milling.yaml`` (a circle R 40 mm at
1200 mm/min on paper 000's drives and PID, a 4-flute end mill, axial depth
1 -> 2 -> 3 mm every 4 s; ``cnc_plant_sim/process/milling.py``) runs in the engine,
all rows in one invocation:

- ``no regulator``: the programmed feed throughout (the force follows the depth);
- ``PI, 4-bit`` (the scenario) and ``PI, continuous`` (no switch);
- ``SMC, 4-bit``: the paper's law with a turning model equivalent to the
  milling gain at the programmed feed (K_s = ∂F/∂r at 2 mm / (2 mm · 1 mm/rev) = 120 N/mm²);
- ``constant override``: no regulator, the feed held at the PI 4-bit run's
  mean applied override from t = 0: the same mean feed without regulation,
  so the contour error the feed level alone explains.

Per row: contour error (max, RMS, mean |e| [µm], the exact distance to the
circle), the path length cut [mm], and per depth segment the mean force,
peak, ripple and switchings per second (``analysis/force.py``).
"""
from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cnc_tools.analysis.scoring import score_run
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.progress import track
from cnc_tools.runs.scenario import Scenario, load_scenario

SCENARIO = "scenarios/paper004_milling.yaml"
#: The SMC's nominal turning model: the milling gain per unit override at 2 mm (240 N) and the programmed feed.
SMC_PARAMS: dict[str, Any] = {"lambda_per_s": 20.0, "eta_n_s2": 1.0e5, "epsilon_fraction": 0.05,
                              "model": {"specific_force_n_mm2": 120.0, "spindle_rpm": 1200.0,
                                        "programmed_feed_mm_rev": 1.0, "interpolator_tau_s": 0.05}}


@dataclass(frozen=True)
class Row:
    """The figures of one run (µm, mm, N, 1/s)."""

    name: str
    contour_max_um: float
    contour_rms_um: float
    contour_mean_um: float
    path_mm: float
    mean_override: float
    segments: tuple[dict[str, Any], ...]


#: A row's scenario: the base scenario and the rows run before it -> the scenario to run.
Variant = Callable[[Scenario, Mapping[str, Row]], Scenario]


def _regulator(scenario: Scenario, **changes: Any) -> Scenario:
    """``scenario`` with its force_regulator section's keys in ``changes`` replaced (not merged)."""
    return scenario.variant(force_regulator={**scenario.raw["force_regulator"], **changes})


def _held_at_mean(scenario: Scenario, rows: Mapping[str, Row]) -> Scenario:
    """No regulator; the override held at the PI 4-bit run's mean applied ratio from the start."""
    ratio = round(rows["PI, 4-bit"].mean_override, 3)
    return scenario.variant(force_regulator=None, feed_override={"max_ratio": 1.5, "schedule": [[0.0, ratio]]})


#: The rows, in order (the constant-override row reads the PI 4-bit row).
CASES: tuple[tuple[str, Variant], ...] = (
    ("no regulator", lambda scenario, rows: scenario.variant(force_regulator=None)),
    ("PI, 4-bit", lambda scenario, rows: scenario),
    ("PI, continuous", lambda scenario, rows: _regulator(
        scenario, quantiser={**scenario.raw["force_regulator"]["quantiser"], "step_ratio": 0.0})),
    ("SMC, 4-bit", lambda scenario, rows: _regulator(scenario, law="smc", law_params=SMC_PARAMS)),
    ("constant override", _held_at_mean),
)


def base_scenario(quick: bool) -> Scenario:
    """The milling scenario (``--quick``: 6 s, the 1 -> 2 mm step only)."""
    return load_scenario(project_root() / SCENARIO, {"duration_s": 6.0} if quick else None)


def _per_segment(run: RunRecord, starts_s: list[float], error_m: np.ndarray,
                 stamp_ns: np.ndarray) -> list[tuple[float, float]]:
    """(RMS contour error [µm], mean override) of each depth segment starting at ``starts_s`` [s]."""
    t_s, ends = stamp_ns * 1e-9, [*starts_s[1:], np.inf]
    ratio = None if run.reference is None else run.reference.feed_override_ratio
    out = []
    for start_s, end_s in zip(starts_s, ends):
        window = (t_s >= start_s) & (t_s < end_s)
        mean_ratio = 1.0 if ratio is None else float(np.mean(ratio[(run.time_s >= start_s) & (run.time_s < end_s)]))
        out.append((float(np.sqrt(np.mean(error_m[window] ** 2))) * 1e6, mean_ratio))
    return out


def measure(name: str, run: RunRecord, reference_n: float) -> Row:
    """The row of ``run``: contour error, path cut, mean override and, per depth segment, force and contour."""
    score = score_run(run, force_reference_n=reference_n)
    assert score.force is not None, "the milling run cuts"
    values = score.contour.values_si
    path_mm = float(np.sum(np.linalg.norm(np.diff(run.joint_states.position_m, axis=0), axis=1))) * 1e3
    ratio = None if run.reference is None else run.reference.feed_override_ratio
    contour = _per_segment(run, [s.start_s for s in score.force.segments], score.series.error_m,
                           score.series.stamp_ns)
    segments = tuple({"depth_mm": s.depth_mm, "mean_n": s.mean_n, "peak_n": s.peak_n, "ripple_n": s.ripple_n,
                      "switchings_per_s": s.switchings_per_s, "contour_rms_um": rms_um, "mean_override": r}
                     for s, (rms_um, r) in zip(score.force.segments, contour))
    return Row(name, values["max"] * 1e6, values["rms"] * 1e6, values["mean_abs"] * 1e6, path_mm,
               1.0 if ratio is None else float(np.mean(ratio)), segments)


def run_rows(quick: bool) -> dict[str, Row]:
    """Every case in order, in the engine."""
    base, rows = base_scenario(quick), dict[str, Row]()
    assert base.force_regulator is not None, "the milling scenario regulates"
    for name, variant in track(CASES, "paper004-milling runs"):
        print(f"  {name} ...", flush=True)
        rows[name] = measure(name, run_engine(variant(base, rows)), base.force_regulator.setpoint.reference_n)
    return rows


def print_rows(rows: Mapping[str, Row], reference_n: float) -> None:
    """The contour table, the force table and the per-depth contour table, rows side by side."""
    print(format_table(["run", "contour max µm", "RMS µm", "mean |e| µm", "path cut mm", "mean override"],
                       [[r.name, f"{r.contour_max_um:.1f}", f"{r.contour_rms_um:.2f}", f"{r.contour_mean_um:.2f}",
                         f"{r.path_mm:.1f}", f"{r.mean_override:.3f}"] for r in rows.values()]))
    depths = [f"{s['depth_mm']:g} mm" for s in next(iter(rows.values())).segments]
    print(f"\ncutting force per axial depth (F_ref {reference_n:g} N): mean / peak / ripple [N], switchings/s "
          "(mean, ripple and switchings over each segment's last third)")
    print(format_table(["run", *depths], [[r.name] + [
        f"{s['mean_n']:.0f} / {s['peak_n']:.0f} / {s['ripple_n']:.0f}, {s['switchings_per_s']:.0f}"
        for s in r.segments] for r in rows.values()]))
    print("\ncontour error per axial depth: RMS [µm] at the segment's mean override")
    print(format_table(["run", *depths], [[r.name] + [
        f"{s['contour_rms_um']:.1f} at {s['mean_override']:.2f}" for s in r.segments] for r in rows.values()]))


def paper004_milling_bench(options: argparse.Namespace) -> int:
    """Run every case in the engine, print contour error and force side by side, write ``--json``."""
    load = machine()["load_average_1min"]
    settings = base_scenario(True).force_regulator
    assert settings is not None
    reference_n = settings.setpoint.reference_n
    print(f"paper004-milling: {SCENARIO} in the engine (load {load} at start)")
    rows = run_rows(bool(options.quick))
    print_rows(rows, reference_n)
    write_json(options.json, {"bench": "paper004-milling", "scenario": SCENARIO, "reference_n": reference_n,
                              "rows": {name: vars(row) for name, row in rows.items()},
                              "load_average_1min_at_start": load, "machine": machine()})
    return 0
