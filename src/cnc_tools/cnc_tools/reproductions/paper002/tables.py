"""The paper-002 bench's tables: rows as plain values (for JSON) and their printing, the paper's numbers beside ours.

``results`` maps a case key (:mod:`.cases`) to its :class:`~.runs.Result`;
``design`` maps a law to ``{axis: design_report entry}`` (K_pp 40/s, each
axis's own model), see :func:`.bench.design_figures`.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from cnc_tools.analysis.tables import format_table, goal_text
from cnc_tools.reproductions.paper002 import data
from cnc_tools.reproductions.paper002.cases import CONTOURS, INERTIA_ERRORS, LAWS, SPINDLE_OFFSETS, Plan
from cnc_tools.reproductions.paper002.runs import METHODS, PDC_LAWS, Result

Results = Mapping[str, Result]
Design = Mapping[str, Mapping[str, Any]]
#: A law "works" at f_d when it removes at least this share of the f_d line ...
WORKS_REMOVAL = 0.5


def removal(results: Results, group: str, law: str, suffix: str = "") -> float | None:
    """1 − f_d line of ``group/law[suffix]`` / f_d line of ``group/p[suffix]`` (None if either did not run)."""
    found, bare = results.get(f"{group}/{law}{suffix}"), results.get(f"{group}/p{suffix}")
    if found is None or bare is None:
        return None
    return 1.0 - found.measure.fd_pulse / bare.measure.fd_pulse


def _pct(value: float | None) -> str:
    return "-" if value is None else f"{100.0 * value:.1f} %"


def _num(value: float | None, digits: int = 4) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _loops(design: Design, law: str) -> list[Mapping[str, Any]]:
    """Every (axis, inertia error) loop figure of ``law``."""
    return [loop for entry in design[law].values() for loop in entry["loops"]]


def design_peaks(design: Design, law: str, nominal_only: bool = False) -> dict[str, Any]:
    """|S|∞ and the disturbance peak (max over axes and, unless ``nominal_only``, inertia errors), all stable?"""
    loops = [loop for loop in _loops(design, law) if not nominal_only or loop["inertia_error"] == 0.0]
    return {"sensitivity_peak": max(loop["sensitivity_peak"] for loop in loops),
            "disturbance_peak": max(loop["disturbance_peak"] for loop in loops),
            "stable": all(bool(loop["stable"]) for loop in loops),
            "removal_at_fd": min(loop["removal_at_fd"] for loop in loops if loop["inertia_error"] == 0.0)}


# =========================================================================== main table
def main_rows(contour: str, results: Results, design: Design) -> list[dict[str, Any]]:
    """One row per law (and the reference run): RMS, its periodic part, the f_d line, design figures."""
    rows = []
    reference = results[f"{contour}/p/ref"].measure
    rows.append({"run": "reference", "label": "reference: P, no periodic disturbance", "paper_letter": "(a)",
                 "paper_rms_pulse": data.paper_rms("reference"), "rms_pulse": reference.rms_pulse,
                 "fd_pulse": reference.fd_pulse})
    for law in LAWS:
        found = results[f"{contour}/{law}"].measure
        own_ref = results.get(f"{contour}/{law}/ref")
        floor = (own_ref or results[f"{contour}/p/ref"]).measure.rms_pulse
        rows.append({"run": law, "label": METHODS[law], "paper_letter": data.paper_letter(law),
                     "paper_rms_pulse": data.paper_rms(law), "rms_pulse": found.rms_pulse,
                     "floor_rms_pulse": floor, "floor_is_own": own_ref is not None,
                     "periodic_rms_pulse": data.periodic_rms(found.rms_pulse, floor), "fd_pulse": found.fd_pulse,
                     "fd_removal": removal(results, contour, law), **design_peaks(design, law, nominal_only=True)})
    return rows


def print_main(contour: str, rows: Sequence[Mapping[str, Any]], plan: Plan, window: tuple[float, float]) -> None:
    """Our RMS and f_d line beside the paper's (a)-(f)."""
    length = "2.83 s of" if contour == "line" else ("the whole" if plan.circle_s is None else f"{plan.circle_s:g} s of")
    print(f"\n{contour} (120 mm/min; {length} run; constant speed {window[0]:.2f}-{window[1]:.2f} s): "
          "contour error [pulse = 1/2.4 µm]; the paper's RMS are from its line (Fig. 9)")
    print("  floor: RMS of the same law without the periodic disturbance (on the line mostly friction at the start, "
          "the axes sticking while the reference moves; the encoder adds little); periodic = sqrt(RMS² − floor²); "
          "f_d line: lock-in amplitude at 50 Hz; |S|∞, dist. peak, removal (model): design_report, K_pp 40/s, "
          "worst axis")
    print(format_table(
        ["run", "paper", "paper RMS", "RMS", "floor", "periodic", "f_d line", "f_d removed",
         "model removal", "|S|∞", "dist. peak"],
        [[r["label"], r["paper_letter"], _num(r["paper_rms_pulse"]), _num(r["rms_pulse"]),
          _num(r.get("floor_rms_pulse")) + ("" if r.get("floor_is_own", True) else "*"),
          _num(r.get("periodic_rms_pulse")), _num(r["fd_pulse"]), _pct(r.get("fd_removal")),
          _pct(r.get("removal_at_fd")), _num(r.get("sensitivity_peak"), 3), _num(r.get("disturbance_peak"), 3)]
         for r in rows]))
    if any(not r.get("floor_is_own", True) for r in rows):
        print("  * the P loop's floor (--quick runs the reference of the P loop only)")


# =========================================================================== the PDC's share
def share_rows(results: Results) -> list[dict[str, Any]]:
    """Per pair (method -> method + PDC): the paper's share (two readings) and ours (RMS, periodic RMS, f_d line)."""
    paper = data.paper_removals()
    rows = []
    for base, with_pdc in (("p", "pdc"), *data.PDC_PAIRS):
        row: dict[str, Any] = {"pair": f"{METHODS[base]} -> {METHODS[with_pdc]}",
                               "paper_plain": paper.get(with_pdc, {}).get("plain"),
                               "paper_periodic": paper.get(with_pdc, {}).get("periodic")}
        for contour in CONTOURS:
            before, after = results[f"{contour}/{base}"].measure, results[f"{contour}/{with_pdc}"].measure
            floors = [results.get(f"{contour}/{law}/ref", results[f"{contour}/p/ref"]).measure.rms_pulse
                      for law in (base, with_pdc)]
            row[contour] = {"plain": 1.0 - after.rms_pulse / before.rms_pulse,
                            "periodic": 1.0 - data.periodic_rms(after.rms_pulse, floors[1])
                            / max(data.periodic_rms(before.rms_pulse, floors[0]), 1e-12),
                            "fd_line": 1.0 - after.fd_pulse / before.fd_pulse}
        rows.append(row)
    return rows


def print_shares(rows: Sequence[Mapping[str, Any]]) -> None:
    """The share of the periodic error removed by the PDC, the paper's "about 80 %" beside ours."""
    print(f"\nshare of the periodic error removed by adding the PDC (paper: about {100 * data.REMOVAL_CLAIM:.0f} %); "
          "RMS: 1 − RMS ratio; periodic: the same after taking each run's floor out in quadrature (the paper's "
          "with its (a)); f_d: the 50 Hz line")
    cells = [[r["pair"], _pct(r["paper_plain"]), _pct(r["paper_periodic"]),
              *[_pct(r[c][k]) for c in CONTOURS for k in ("plain", "periodic", "fd_line")]] for r in rows]
    print(format_table(["pair", "paper RMS", "paper periodic", "line RMS", "line periodic", "line f_d",
                        "circle RMS", "circle periodic", "circle f_d"], cells))


# =========================================================================== goals
def inertia_rows(results: Results, design: Design, plan: Plan) -> list[dict[str, Any]]:
    """Per PDC stack: removal at each inertia error (with and without the encoder), design peaks, the goal."""
    rows = []
    for law in (name for name in plan.goal_laws if name in PDC_LAWS):
        measured = {eps: removal(results, f"inertia{eps:+.1f}", law) for eps in INERTIA_ERRORS}
        raw = {eps: removal(results, f"inertia{eps:+.1f}", law, "/noenc") for eps in INERTIA_ERRORS}
        peaks = design_peaks(design, law)
        worst = min(v for v in measured.values() if v is not None)
        met = (worst >= data.GOAL_REMOVAL and peaks["stable"] and peaks["sensitivity_peak"] <= data.GOAL_PEAK
               and peaks["disturbance_peak"] <= data.GOAL_PEAK)
        rows.append({"law": law, "label": METHODS[law], "removal": measured, "removal_no_encoder": raw,
                     "nominal_discrete": removal(results, "circle", law), "worst": worst, **peaks,
                     "met": bool(met)})
    return rows


def print_inertia(rows: Sequence[Mapping[str, Any]]) -> None:
    """Goal 1: ≥ 95 % of the f_d line removed with |S|∞ ≤ 2, also with ±20 % inertia."""
    print(f"\ngoal: >= {100 * data.GOAL_REMOVAL:.0f} % of the f_d line removed, |S|∞ <= {data.GOAL_PEAK:g} and no "
          f"band amplified by more than 6 dB (dist. peak <= {data.GOAL_PEAK:g}), also with ±"
          f"{100 * data.GOAL_INERTIA_ERROR:.0f} % inertia (plant: PI loops with K_t/J / (1 + ε); circle; "
          "peaks: design_report over both axes and ε; 'no enc.': the same runs without the encoder)")
    header = ["stack", "discrete"] + [f"ε {eps:+.1f}" for eps in INERTIA_ERRORS] + \
             [f"ε {eps:+.1f} no enc." for eps in INERTIA_ERRORS] + ["|S|∞", "dist. peak", "stable", "goal"]
    print(format_table(header, [[r["label"], _pct(r["nominal_discrete"]),
                                 *[_pct(r["removal"][e]) for e in INERTIA_ERRORS],
                                 *[_pct(r["removal_no_encoder"][e]) for e in INERTIA_ERRORS],
                                 _num(r["sensitivity_peak"], 3), _num(r["disturbance_peak"], 3),
                                 "yes" if r["stable"] else "NO", goal_text(r["met"])] for r in rows]))
    best = max(rows, key=lambda r: (r["met"], r["worst"]))
    print(f"  best stack: {best['label']} (worst removal {_pct(best['worst'])}): {goal_text(best['met'])}")


def spindle_rows(results: Results, plan: Plan) -> list[dict[str, Any]]:
    """Per PDC stack: removal with the spindle ±5 % off the 1500 rpm design, and redesigned for it."""
    rows = []
    for law in (name for name in plan.goal_laws if name in PDC_LAWS):
        groups = {offset: f"spindle{100 * offset:+.0f}%" for offset in SPINDLE_OFFSETS}
        held = {o: removal(results, g, law) for o, g in groups.items()}
        redesigned = {o: _redesigned(results, g, law) for o, g in groups.items()}
        worst = min(v for v in held.values() if v is not None)
        rows.append({"law": law, "label": METHODS[law], "held": held, "redesigned": redesigned, "worst": worst,
                     "met": bool(worst >= data.GOAL_SPINDLE_REMOVAL)})
    return rows


def _redesigned(results: Results, group: str, law: str) -> float | None:
    found, bare = results.get(f"{group}/{law}/redesigned"), results.get(f"{group}/p")
    return None if found is None or bare is None else 1.0 - found.measure.fd_pulse / bare.measure.fd_pulse


def print_spindle(rows: Sequence[Mapping[str, Any]]) -> None:
    """Goal 2: ≥ 90 % with the spindle held within ±5 % of the design."""
    print(f"\ngoal: >= {100 * data.GOAL_SPINDLE_REMOVAL:.0f} % of the f_d line removed with the spindle held "
          f"±{100 * data.GOAL_SPINDLE_TOLERANCE:.0f} % off the 1500 rpm design (circle); 'redesigned': the PDC "
          "designed for the plant's speed (what a redesign on line gives)")
    header = ["stack"] + [f"{100 * o:+.0f} % held" for o in SPINDLE_OFFSETS] + \
             [f"{100 * o:+.0f} % redesigned" for o in SPINDLE_OFFSETS] + ["goal (held)"]
    print(format_table(header, [[r["label"], *[_pct(r["held"][o]) for o in SPINDLE_OFFSETS],
                                 *[_pct(r["redesigned"][o]) for o in SPINDLE_OFFSETS], goal_text(r["met"])]
                                for r in rows]))
    best = max(rows, key=lambda r: r["worst"])
    print(f"  best stack: {best['label']} (worst {_pct(best['worst'])} held): {goal_text(best['met'])}"
          + ("" if best["met"] else "; the remedy, the redesign on line, is the next table"))


# =========================================================================== beyond the paper
def sweep_rows(results: Results, predictions: Mapping[str, Mapping[float, Mapping[str, Any]]],
               plan: Plan) -> list[dict[str, Any]]:
    """Per f_d: measured removal per law, the P loop's f_d line and floor, the design's figures per law."""
    rows = []
    for f_hz in plan.sweep_hz:
        group = f"sweep{f_hz:g}"
        rows.append({"f_d_hz": f_hz, "bare_fd_pulse": results[f"{group}/p"].measure.fd_pulse,
                     "floor_fd_pulse": results[f"{group}/p/ref"].measure.fd_pulse,
                     "removal": {law: removal(results, group, law) for law in plan.sweep_laws if law != "p"},
                     "design": {law: predictions[law].get(f_hz) for law in predictions}})
    return rows


def print_sweep(rows: Sequence[Mapping[str, Any]], plan: Plan) -> None:
    """The f_d sweep: measured removal (engine) and the design's disturbance peak per law."""
    laws = [law for law in plan.sweep_laws if law != "p"]
    print(f"\nbeyond the paper: f_d sweep (circle, {plan.side_s:g} s, no encoder; each law designed for the f_d; "
          "A the same); removal of the f_d line measured [the design's disturbance peak per axis, worst of ±20 % "
          "inertia]; "
          "floor: the P loop's f_d line with the encoder and no disturbance")
    cells = []
    for r in rows:
        entries = []
        for law in laws:
            figure = r["design"].get(law)
            peak = "-" if figure is None else "refused" if "error" in figure else " / ".join(
                f"{fig['disturbance_peak']:.2f} {axis}" for axis, fig in figure["axes"].items())
            entries.append(f"{_pct(r['removal'][law])} [{peak}]")
        cells.append([f"{r['f_d_hz']:g}", _num(r["bare_fd_pulse"]), _num(r["floor_fd_pulse"]), *entries])
    print(format_table(["f_d Hz", "P f_d line", "floor", *[METHODS[law] for law in laws]], cells))


def worst_of_axes(per_axis: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """One law's design figures at one f_d over its axes: the worst of each figure, and each axis's own.

    ``per_axis`` maps an axis to :func:`.bench.sweep_prediction`'s figures (or ``{"error": ...}``: refused).
    """
    refused = {axis: fig["error"] for axis, fig in per_axis.items() if "error" in fig}
    if refused:
        return {"error": "; ".join(f"{axis}: {text}" for axis, text in refused.items()), "axes": dict(per_axis)}
    peak_axis = max(per_axis, key=lambda axis: per_axis[axis]["disturbance_peak"])
    return {"removal_at_fd": min(fig["removal_at_fd"] for fig in per_axis.values()),
            "removal_at_fd_worst": min(fig["removal_at_fd_worst"] for fig in per_axis.values()),
            "disturbance_peak": per_axis[peak_axis]["disturbance_peak"], "disturbance_peak_axis": peak_axis,
            "sensitivity_peak": max(fig["sensitivity_peak"] for fig in per_axis.values()),
            "stable": all(bool(fig["stable"]) for fig in per_axis.values()), "axes": dict(per_axis)}


def _works(fig: Mapping[str, Any] | None) -> bool:
    """Removal >= 50 % at f_d, disturbance peak <= 2, stable at ±20 % inertia (a refused design does not work)."""
    return (fig is not None and "error" not in fig and fig["removal_at_fd"] >= WORKS_REMOVAL
            and fig["disturbance_peak"] <= data.GOAL_PEAK and bool(fig["stable"]))


def works_summary(predictions: Mapping[str, Mapping[float, Mapping[str, Any]]]) -> dict[str, dict[str, list[float]]]:
    """Per law and axis (and ``"both"``), the f_d [Hz] of the design grid where it works (:func:`_works`);
    ``"worse"``: where it makes the f_d line worse on some axis at some inertia error (removal < 0)."""
    out: dict[str, dict[str, list[float]]] = {}
    for law, per_f in predictions.items():
        axes = sorted({axis for fig in per_f.values() for axis in fig.get("axes", {})})
        out[law] = {axis: [f for f, fig in per_f.items() if _works(fig.get("axes", {}).get(axis))] for axis in axes}
        out[law]["both"] = [f for f, fig in per_f.items() if _works(fig)]
        out[law]["worse"] = [f for f, fig in per_f.items() if "error" not in fig and fig["removal_at_fd_worst"] < 0.0]
    return out


def print_works(summary: Mapping[str, Mapping[str, Sequence[float]]], grid: Sequence[float]) -> None:
    """Where each law works on the design grid, per axis and on both."""
    print(f"  where each law works (design grid {grid[0]:g}-{grid[-1]:g} Hz: removes >= {100 * WORKS_REMOVAL:.0f} % "
          f"at f_d, no band amplified by > 6 dB, stable with ±20 % inertia; each axis with its own model; "
          "worse: the f_d line grows on some axis at some inertia error):")
    for law, by_axis in summary.items():
        for axis, freqs in by_axis.items():
            span = "nowhere" if not freqs else ", ".join(f"{f:g}" for f in freqs)
            print(f"    {METHODS[law]:18s} {axis:4s} {span}")


def step_rows(results: Results, plan: Plan) -> list[dict[str, Any]]:
    """Per spindle step: the f_d line at the new f_d after the step, per law, and its removal against P."""
    rows = []
    for offset in plan.step_offsets:
        group = f"step{100 * offset:+.0f}%"
        for law in plan.step_laws:
            found = results[f"{group}/{law}"].measure
            rows.append({"step": offset, "law": law, "label": METHODS[law], "f_d_hz": found.f_d_hz,
                         "window_s": found.window_s, "fd_pulse": found.fd_pulse,
                         "removal": removal(results, group, law)})
    return rows


def print_steps(rows: Sequence[Mapping[str, Any]], plan: Plan) -> None:
    """The spindle step with every law at its design (the PDC at 1500 rpm; on line: :mod:`.online`)."""
    print(f"\nbeyond the paper: spindle step at {plan.step_at_s:g} s (circle), every law at its design (the PDC "
          f"at 1500 rpm); measured from {plan.step_at_s:g} s + 0.3 s at the new f_d")
    print(format_table(["step", "law", "new f_d Hz", "f_d line", "removed"],
                       [[f"{100 * r['step']:+.0f} %", r["label"], f"{r['f_d_hz']:g}", _num(r["fd_pulse"]),
                         _pct(r["removal"])] for r in rows]))
