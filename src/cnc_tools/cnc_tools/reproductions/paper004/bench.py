"""Bench ``paper004``: the floors beside issue 12's estimates, the paper's comparison, the SMC from rest, the preview.

Printed:

1. the model's floors (overshoot with the feed cut to zero at the step, the
   fastest settling into ±5 %, the override 500 N needs, the switch levels at
   3 mm) beside issue 12's estimates;
2. adaptive, SMC (λ 20, η 0.1, ε 5 %) and PI, continuous and 4-bit, from
   steady cutting: overshoot at each depth step beside its floor, settling,
   steady ripple, offset and switchings per second per depth;
3. the paper's claims (it gives figures, no numbers) with our verdicts;
4. the SMC from rest;
5. the preview plan (SMC as the feedback), right and deliberately wrong;
6. issue 12's goals for our best regulator under the 4-bit switch; 6b. ours with each
   depth step at each millisecond of the update period, with and without its depth-jump test;

and the force-trace figures (``fig_*.png``) in the output folder.
``--quick``: 6 s runs (the 1 -> 2 mm step only), no ε study, two preview rows, no 6b.
"""
from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.force import PreviewConfig
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.reproductions.paper004 import data
from cnc_tools.reproductions.paper004.figures import write_figure
from cnc_tools.reproductions.paper004.floors import StepFloor, level_forces_n, levels_in_band, step_floor
from cnc_tools.reproductions.paper004.runs import (
    EPSILON_CASES,
    EPSILONS,
    MAIN_CASES,
    OURS_CASES,
    OURS_NO_JUMP,
    PREVIEW_CASES,
    REST_CASES,
    UPDATE_PERIOD_S,
    Result,
    paper_model,
    run_case,
    step_phase_overshoots,
    switch,
)
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.progress import track

#: The depth steps of the scenario.
STEPS: tuple[tuple[float, float], ...] = ((1.0, 2.0), (2.0, 3.0))


#: Most override changes per second at a steady depth (issue 26).
MAX_CHANGES_PER_S = 2.0


def floors(delay_s: float = 0.0) -> dict[tuple[float, float], StepFloor]:
    """The floor of each depth step of the scenario, the feed cut ``delay_s`` [s] after the step."""
    return {s: step_floor(paper_model(), s, data.REFERENCE_N, data.BAND_FRACTION, delay_s) for s in STEPS}


def print_floors(step_floors: dict[tuple[float, float], StepFloor]) -> dict[str, Any]:
    """Section 1 (floors and levels beside issue 12's estimates); returns the figures."""
    model, levels, late = paper_model(), switch(True), floors(UPDATE_PERIOD_S)
    rows = [[f"{a:g} -> {b:g} mm", f"{data.ISSUE_FLOOR_OVERSHOOT_PCT[(a, b)]:.0f}", f"{f.overshoot_pct:.1f}",
             f"{late[(a, b)].overshoot_pct:.1f}", f"{data.ISSUE_FLOOR_SETTLING_S[(a, b)]:.2f}", f"{f.settling_s:.3f}"]
            for (a, b), f in step_floors.items()]
    print("1. Floors from the model (feed cut to zero at the step, or one update period after it: the first"
          " update that can see the step; steady at 500 N before it)")
    print(format_table(["step", "overshoot issue [%]", "ours [%]", f"cut {1e3 * UPDATE_PERIOD_S:g} ms late [%]",
                        "settling issue [s]", "ours [s]"], rows))
    ratio_pct = 100.0 * model.steady_ratio(data.REFERENCE_N, 1.0)
    at3 = level_forces_n(model, 3.0, levels)
    print(f"  override for 500 N at 1 mm: issue ≈{data.ISSUE_RATIO_AT_1MM_PCT:g} %, ours {ratio_pct:.1f} %"
          " (the switch's nearest level 140 % gives "
          f"{model.steady_force_n(1.4, 1.0):.0f} N)")
    for ratio, force in data.ISSUE_FORCE_AT_3MM_N.items():
        print(f"  at 3 mm, {100 * ratio:.0f} %: issue ≈{force:g} N, ours {at3[ratio]:.1f} N")
    band = {d: levels_in_band(model, d, levels, data.REFERENCE_N, data.BAND_FRACTION) for d in (1.0, 2.0, 3.0)}
    print("  levels within ±5 % of 500 N: " + ", ".join(f"{d:g} mm: {[f'{100 * r:.0f} %' for r in v] or 'none'}"
                                                       for d, v in band.items()))
    return {"steps": {f"{a:g}->{b:g}": vars(f) for (a, b), f in step_floors.items()},
            "steps_cut_one_update_late": {f"{a:g}->{b:g}": vars(f) for (a, b), f in late.items()},
            "ratio_for_500n_at_1mm_pct": ratio_pct, "levels_in_band": {str(d): v for d, v in band.items()}}


def _settle(value: float | None) -> str:
    return "never" if value is None else f"{value:.3f}"


def result_rows(results: Sequence[Result], step_floors: dict[tuple[float, float], StepFloor]) -> list[list[Any]]:
    """One row per run and depth step: overshoot beside the floor, settling, ripple, offset, switchings."""
    rows = []
    for r in results:
        for seg in r.segments[1:]:
            floor = next(f for s, f in step_floors.items() if s[1] == seg.depth_mm)
            rows.append([r.case.label, f"{seg.depth_mm - 1:g} -> {seg.depth_mm:g}", f"{seg.overshoot_pct:.1f}",
                         f"{seg.step_overshoot_pct:.1f}", f"{floor.overshoot_pct:.1f}", f"{seg.undershoot_pct:.1f}",
                         _settle(seg.settling_s), f"{floor.settling_s:.3f}", f"{seg.ripple_n:.1f}",
                         f"{seg.mean_n - data.REFERENCE_N:+.1f}",
                         round(seg.switchings_per_s, 1) if r.case.quantised else "cont."])
    return rows


RESULT_HEADER = ["run", "step [mm]", "overshoot [%]", "in 0.5 s [%]", "floor [%]", "undershoot [%]", "settling [s]",
                 "floor [s]", "ripple p-p [N]", "offset [N]", "switch/s"]


def print_results(title: str, results: Sequence[Result], step_floors: dict[tuple[float, float], StepFloor]) -> None:
    """A table of :func:`result_rows` under ``title``."""
    print(title)
    print(format_table(RESULT_HEADER, result_rows(results, step_floors)))


def _some(flags: Sequence[bool]) -> str:
    """"yes" when every flag holds, "partly" when some do, "no" when none."""
    return "yes" if all(flags) else ("partly" if any(flags) else "no")


def claims(results: dict[str, Result]) -> list[list[Any]]:
    """The paper's claims with our verdict and the measurements behind it (needs both steps)."""
    def over(key: str) -> list[float]:
        return [round(float(s.overshoot_pct), 1) for s in results[key].segments[1:]]

    def ripple(key: str) -> float:
        return round(float(max(s.ripple_n for s in results[key].segments[1:])), 1)

    adaptive_c, adaptive_q, smc_q = over("adaptive/cont"), over("adaptive/4bit"), over("smc/4bit")
    rates = [results[f"smc-eps{e:g}/4bit"].switchings_per_s for e in EPSILONS]
    cycles = [s.switchings_per_s > 0.0 for s in results["adaptive/4bit"].segments]
    return [
        [data.CLAIMS["adaptive_overshoots"], _some([min(adaptive_c) > 5.0]), f"overshoot {adaptive_c} %"],
        [data.CLAIMS["adaptive_oscillates"], _some(cycles),
         f"steady switchings/s per depth {[round(s.switchings_per_s, 1) for s in results['adaptive/4bit'].segments]}; "
         f"ripple {ripple('adaptive/4bit')} N vs {ripple('adaptive/cont')} N continuous; overshoot {adaptive_q} %"],
        [data.CLAIMS["smc_less_overshoot"], _some([s < a for s, a in zip(smc_q, adaptive_q)]),
         f"SMC {smc_q} % vs adaptive {adaptive_q} % (4-bit)"],
        [data.CLAIMS["smc_bounded_chatter"], _some([ripple("smc/4bit") <= 2.0 * data.BAND_FRACTION * data.REFERENCE_N]),
         f"ripple {ripple('smc/4bit')} N <= 2 ε F_ref = {2 * data.BAND_FRACTION * data.REFERENCE_N:g} N"],
        [data.CLAIMS["phi_sets_chatter"], _some([bool(np.all(np.diff(rates) <= 0.0))]),
         "switchings/s at ε " + ", ".join(f"{100 * e:g} %: {r:.1f}" for e, r in zip(EPSILONS, rates))],
    ]


def _first_in_band_s(result: Result) -> float | None:
    t, f = result.traces.t_s, result.traces.force_n
    inside = abs(f - data.REFERENCE_N) <= data.BAND_FRACTION * data.REFERENCE_N
    return float(t[inside.argmax()]) if inside.any() else None


def print_rest(results: Sequence[Result]) -> dict[str, Any]:
    """Section 4: when (if ever) the SMC from rest first reaches ±5 % of 500 N."""
    print("4. SMC (η = 0.1) from rest: first time within ±5 % of 500 N")
    rows = [[r.case.label, _settle(_first_in_band_s(r)), round(float(r.traces.force_n[r.traces.t_s <= 3.5].max()), 1)]
            for r in results]
    print(format_table(["run", "first in band [s]", "largest force before 3.5 s [N]"], rows))
    return {r.case.key: _first_in_band_s(r) for r in results}


def goal_rows(result: Result, step_floors: dict[tuple[float, float], StepFloor], preview: bool) -> list[list[Any]]:
    """Issue 12's goals for one 4-bit run (``preview``: overshoot <= 5 % instead of 1.2 × the floor)."""
    model, levels, rows = paper_model(), switch(True), []
    for seg in result.segments[1:]:
        floor = next(f for s, f in step_floors.items() if s[1] == seg.depth_mm)
        limit = 5.0 if preview else 1.2 * floor.overshoot_pct
        step_force = model.steady_force_n(levels.step_ratio, seg.depth_mm)
        lands = bool(levels_in_band(model, seg.depth_mm, levels, data.REFERENCE_N, data.BAND_FRACTION))
        in_band = abs(seg.mean_n - data.REFERENCE_N) <= data.BAND_FRACTION * data.REFERENCE_N
        cycle_free = in_band and seg.switchings_per_s <= (0.0 if lands else MAX_CHANGES_PER_S)
        cycle_goal = ("mean ±5 %, no changes (a level lands)" if lands
                      else f"mean ±5 %, <= {MAX_CHANGES_PER_S:g} changes/s (no level lands)")
        cycle = f"{seg.switchings_per_s:.1f}/s, offset {seg.mean_n - data.REFERENCE_N:+.1f} N"
        rows += [[f"{seg.depth_mm:g} mm", f"step overshoot (0.5 s) <= {limit:.2f} %", f"{seg.step_overshoot_pct:.2f}",
                  goal_text(seg.step_overshoot_pct <= limit)],
                 [f"{seg.depth_mm:g} mm", "settling <= 0.5 s", _settle(seg.settling_s),
                  goal_text(seg.settling_s is not None and seg.settling_s <= 0.5)],
                 [f"{seg.depth_mm:g} mm", cycle_goal, cycle, goal_text(cycle_free)],
                 [f"{seg.depth_mm:g} mm", f"ripple <= one step ({step_force:.0f} N)", f"{seg.ripple_n:.1f}",
                  goal_text(seg.ripple_n <= step_force)]]
    return rows


def print_goals(results: dict[str, Result], step_floors: dict[tuple[float, float], StepFloor]) -> dict[str, Any]:
    """Section 6: the goals for the SMC alone and with the preview, both 4-bit."""
    figures: dict[str, Any] = {}
    for key, preview in (("smc/4bit", False), ("ours/4bit", False), ("preview/4bit", True),
                         ("preview-ours/4bit", True)):
        if key not in results:
            continue
        rows = goal_rows(results[key], step_floors, preview)
        rate = results[key].switchings_per_s
        print(f"6. Goals, {results[key].case.label} (switchings {rate:.1f}/s over the run; "
              f"at most {1 / 0.01:.0f}/s at the 10 ms update period)")
        print(format_table(["depth", "goal", "ours", "verdict"], rows))
        figures[key] = rows
    return figures


#: The step's phases in the update period of section 6b [s].
STEP_PHASES_S = tuple(1.0e-3 * k for k in range(10))


def print_step_phases() -> dict[str, Any]:
    """Section 6b: ours, 4-bit, each step's overshoot with the step at each millisecond of the update period."""
    ours = next(c for c in OURS_CASES if c.key == "ours/4bit")
    goal = {s: 1.2 * f.overshoot_pct for s, f in floors().items()}
    rows, figures = [], {}
    for case in (ours, OURS_NO_JUMP):
        for step in STEPS:
            values = step_phase_overshoots(case, step, STEP_PHASES_S)
            above = sum(v > goal[step] for v in values)
            rows.append([case.label, f"{step[0]:g} -> {step[1]:g} mm", " ".join(f"{v:.1f}" for v in values),
                         f"{max(values):.2f}", f"{goal[step]:.2f}", f"{above} of {len(values)}"])
            figures[f"{case.key} {step[0]:g}->{step[1]:g}"] = values
    print("6b. The step anywhere in the 10 ms update period (ours, 4-bit, from steady cutting; phase 0: an update "
          "1 ms after the step)")
    print(format_table(["run", "step", "overshoot [%] at phase 0 ... 9 ms", "max [%]", "goal [%]", "above goal"],
                       rows))
    return figures


def _out_dir(options: argparse.Namespace) -> Path:
    out = getattr(options, "out", None)
    return Path(out) if out else project_root() / "bags" / "bench" / options.name / timestamp()


def _run_all(quick: bool) -> dict[str, Result]:
    duration = 6.0 if quick else data.DURATION_S
    preview = PreviewConfig()
    cases = MAIN_CASES + OURS_CASES + REST_CASES + (PREVIEW_CASES[:2] if quick else EPSILON_CASES + PREVIEW_CASES)
    return {c.key: run_case(c, duration, preview) for c in track(cases, "paper004 runs")}


def _figures(out: Path, results: dict[str, Result]) -> list[str]:
    groups = {"fig_adaptive.png": ("Adaptive (Figs. 1, 2)", "adaptive/"), "fig_smc.png": ("SMC (Figs. 4, 5)", "smc/"),
              "fig_pi.png": ("PI", "pi/"), "fig_smc_rest.png": ("SMC from rest", "smc-rest/"),
              "fig_preview.png": ("SMC + preview", "preview")}
    return [str(write_figure(out / name, title, [r for k, r in results.items() if k.startswith(prefix)]))
            for name, (title, prefix) in groups.items()]


def paper004_bench(options: argparse.Namespace) -> int:
    """Run the paper-004 bench (module docstring); 0 on success."""
    quick, start = bool(getattr(options, "quick", False)), time.perf_counter()
    step_floors = floors()
    figures: dict[str, Any] = {"floors": print_floors(step_floors), "machine": machine()}
    results = _run_all(quick)
    main = [results[c.key] for c in MAIN_CASES]
    print_results("2. The paper's comparison, from steady cutting at 500 N (floor: section 1)", main, step_floors)
    print_results("2b. Ours for the switch: the paper's SMC to reach the layer, an integral in it, hysteresis "
                  f"{data.OURS_HYSTERESIS:g} of a level", [results[c.key] for c in OURS_CASES[:2]], step_floors)
    if not quick:
        print("3. The paper's claims (Figs. 1, 2, 4, 5; the paper gives no numbers)")
        print(format_table(["claim", "holds", "measured"], claims(results)))
    figures["rest"] = print_rest([results[c.key] for c in REST_CASES])
    preview = [r for k, r in results.items() if k.startswith("preview")]
    print_results("5. Preview from the depth schedule (SMC as feedback; goal overshoot <= 5 % with the right one)",
                  preview, step_floors)
    figures["goals"] = print_goals(results, step_floors)
    if not quick:
        figures["step_phases"] = print_step_phases()
    figures["runs"] = {k: [vars(s) for s in r.segments] for k, r in results.items()}
    written = _figures(_out_dir(options), results)
    print(f"figures: {', '.join(written)}")
    figures["wall_s"] = time.perf_counter() - start
    print(f"wall time {figures['wall_s']:.1f} s")
    write_json(getattr(options, "json", None), figures)
    return 0 if all(math.isfinite(f.overshoot_pct) for f in step_floors.values()) else 1
