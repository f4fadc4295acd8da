"""Bench ``paper000-assumptions``: how much each assumption the paper leaves open moves Table 5.

Each variant changes one thing against the baseline (the shipped
``scenarios/paper000_*.yaml``, the ``paper`` view) and reruns the six Table 5
cases with the PID and the FLC in the engine over a few seeds, scored by the
same scorer. Two tables: the PID's max/RMS per case, and the FLC/PID ratios
per case. ``docs/reproduction.md`` quotes them.
"""
from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.reproductions.paper000.runs import CONTROLLERS, VIEWS, Controller
from cnc_tools.reproductions.paper000.sweep import Case, Settings, Sweep, run_sweep, settings_of, table5_cases
from cnc_tools.runs.progress import track

#: Seeds when ``--seeds`` is not given.
DEFAULT_SEEDS = 3
#: A case name -> the scenario overrides of a variant for that case.
Overrides = Callable[[str], Mapping[str, Any]]


def _none(case: str) -> Mapping[str, Any]:
    return {}


def _all(overrides: Mapping[str, Any]) -> Overrides:
    return lambda case: overrides


def _only(prefix: str, overrides: Mapping[str, Any]) -> Overrides:
    return lambda case: overrides if case.startswith(prefix) else {}


@dataclass(frozen=True)
class Variant:
    """One assumption changed: scenario overrides per case, the scored view, controller parameter changes."""

    name: str
    assumption: str
    description: str
    overrides: Overrides = _none
    view: str = "paper"
    law_params: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)  # controller -> extra params

    def controllers(self) -> dict[str, Controller]:
        """PID and FLC with this variant's parameter changes."""
        return {name: dataclasses.replace(CONTROLLERS[name], law_params={
            **CONTROLLERS[name].law_params, **self.law_params.get(name, {})}) for name in ("pid", "flc")}


_WIDE_DAC = {"pid": {"state_limit": 2047.0}, "flc": {"integral_limit": 2047.0}}

#: The variants, baseline first.
VARIANTS: tuple[Variant, ...] = (
    Variant("baseline", "-", "shipped scenarios, paper view"),
    Variant("whole_run", "window scored", VIEWS["whole_run"].description, view="whole_run"),
    Variant("after_start", "window scored", VIEWS["after_start"].description, view="after_start"),
    Variant("accel_100", "acceleration limit", "100 mm/s² per axis (baseline 250)",
            _all({"limits": {"max_acceleration_mm_s2": 100}})),
    Variant("accel_1000", "acceleration limit", "1000 mm/s² per axis",
            _all({"limits": {"max_acceleration_mm_s2": 1000}})),
    Variant("accel_step", "acceleration profile", "1e5 mm/s²: feed reached within one sample (no profile)",
            _all({"limits": {"max_acceleration_mm_s2": 100000}})),
    Variant("line_100mm", "line length", "lines 100 mm long (baseline 50 mm)",
            _only("line", {"program": {"length_mm": 100}})),
    Variant("corner_leg_40mm", "corner shape", "legs 40 mm (baseline 20 mm)",
            _only("corner", {"program": {"leg_mm": 40}})),
    Variant("corner_turn_135", "corner shape", "turn 135° (a 45° corner; baseline 90°)",
            _only("corner", {"program": {"angle_deg": 135}})),
    Variant("circle_start_0deg", "circle start", "start at 0° from the centre (baseline −90°: centre (0, r))",
            _only("circle", {"program": {"start_angle_deg": 0}})),
    Variant("nominal_plant", "variation draws", "no variation of K, τ, friction",
            _all({"plant": {"variation": {"gain_pct": 0, "time_constant_pct": 0, "friction_pct": 0}}})),
    Variant("friction_0pct", "variation draws", "friction not varied (K, τ still ±5 %)",
            _all({"plant": {"variation": {"friction_pct": 0}}})),
    Variant("substeps_10", "plant integration", "10 sub-steps per sample (baseline 1, exact ZOH lag)",
            _all({"plant": {"substeps": 10}})),
    Variant("no_quantisation", "quantisation", "command not quantised (baseline 1 DAC unit)",
            _all({"servo": {"quantum": 0}})),
    Variant("dac_12bit", "DAC range", "±2047 (12 bit) instead of ±127, PID state and FLC integral too",
            _all({"servo": {"output_limit": 2047}}), law_params=_WIDE_DAC),
    Variant("ke_2", "K_e", "encoder gain 2 counts/BLU (error seen by the laws doubles)",
            _all({"servo": {"counts_per_m": 200000}})),
    Variant("ke_0.5", "K_e", "encoder gain 0.5 counts/BLU", _all({"servo": {"counts_per_m": 50000}})),
    Variant("flc_u_scale_1.5", "FLC scaling", "FLC u_scale 1.5 (PID unchanged: not equivalent gains)",
            law_params={"flc": {"u_scale": 1.5}}),
    Variant("both_gains_1.5", "FLC scaling", "FLC u_scale 1.5 and PID kp, kd × 1.5 (equivalent gains again)",
            law_params={"flc": {"u_scale": 1.5}, "pid": {"kp": 3.6, "kd": 0.1005}}),  # kd 10.05 per sample
    Variant("flc_range_x2", "FLC scaling", "FLC e_scale, de_scale 0.5 and u_scale 2: same equivalent gains, "
            "twice the range (±110 DAC)", law_params={"flc": {"e_scale": 0.5, "de_scale": 0.5, "u_scale": 2.0}}),
    Variant("flc_e_scale_2", "FLC scaling", "FLC e_scale 2 (sets reached at half the error)",
            law_params={"flc": {"e_scale": 2.0}}),
    Variant("flc_de_scale_2", "FLC scaling", "FLC de_scale 2", law_params={"flc": {"de_scale": 2.0}}),
    Variant("ki_0.2", "integral gain", "ki 0.2 per sample for both (Table 4: 0.1), 20 /s",
            law_params={"flc": {"ki": 20.0}, "pid": {"ki": 20.0}}),
)


def run_variant(variant: Variant, settings: Settings) -> Sweep:
    """The six cases (``--quick``: one) with PID and FLC under ``variant``, in the engine."""
    cases = [Case(c.name, c.path, variant.overrides(c.name)) for c in table5_cases(settings.quick)]
    return run_sweep(cases, ["pid", "flc"], settings.plan(graph_seeds=0),
                     lookup=variant.controllers())


def variant_rows(variant: Variant, sweep: Sweep, cases: Sequence[str]) -> dict[str, Any]:
    """Mean PID and FLC max/RMS [BLU] per case under the variant's view, and the FLC/PID ratios."""
    out: dict[str, Any] = {"variant": variant.name, "assumption": variant.assumption,
                           "description": variant.description, "view": variant.view, "cases": {}}
    for case in cases:
        means = {(c, m): sweep.mean(case, c, m, variant.view) for c in ("pid", "flc") for m in ("max", "rms")}
        out["cases"][case] = {f"{c}_{m}_blu": v for (c, m), v in means.items()} | {
            f"flc_to_pid_{m}": means[("flc", m)] / means[("pid", m)] for m in ("max", "rms")}
    return out


def print_variants(rows: Sequence[dict[str, Any]], cases: Sequence[str]) -> None:
    """PID max/RMS per case, then FLC/PID max/RMS per case, one line per variant."""
    print("\nPID: mean max / RMS contour error [BLU] per case")
    print(format_table(["variant", *cases], [[r["variant"], *(
        f"{r['cases'][c]['pid_max_blu']:.2f}/{r['cases'][c]['pid_rms_blu']:.2f}" for c in cases)] for r in rows]))
    print("\nFLC/PID: ratio of mean max / ratio of mean RMS per case (< 1: the FLC is better)")
    print(format_table(["variant", *cases], [[r["variant"], *(
        f"{r['cases'][c]['flc_to_pid_max']:.2f}/{r['cases'][c]['flc_to_pid_rms']:.2f}" for c in cases)] for r in rows]))
    print("\nvariants:")
    print(format_table(["variant", "assumption", "what changes"],
                       [[r["variant"], r["assumption"], r["description"]] for r in rows]))


def paper000_assumptions_bench(options: argparse.Namespace) -> int:
    """Every variant of :data:`VARIANTS`: PID and FLC on the Table 5 cases, in the engine."""
    started = time.perf_counter()
    settings = settings_of(options, default_seeds=DEFAULT_SEEDS)
    cases = [c.name for c in table5_cases(settings.quick)]
    print(f"paper000-assumptions: {len(VARIANTS)} variants x {len(cases)} cases x PID, FLC x seeds "
          f"{list(settings.seeds)}, engine", flush=True)
    rows = [variant_rows(v, run_variant(v, settings), cases) for v in track(VARIANTS, "paper000 variants")]
    print_variants(rows, cases)
    wall_s = time.perf_counter() - started
    print(f"\nwall time: {wall_s:.1f} s")
    write_json(settings.json, {"bench": "paper000-assumptions", "seeds": list(settings.seeds),
                               "machine": machine(), "wall_time_s": wall_s, "variants": rows})
    return 0
