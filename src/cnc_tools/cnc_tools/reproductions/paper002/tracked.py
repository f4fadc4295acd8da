"""The PDC estimating f_d on line, without a spindle schedule (``track_fd``): removal per spindle deviation, and
the loop figures of every design the tracker can pick.

- runs (:func:`.cases.track_cases`): the circle with the plant's spindle held at 1500 rpm · (1 + δ), the servo
  commanding 1500 rpm and knowing nothing else; removal of the f_d line against the P loop, per PDC stack at its
  1500 rpm design and tracking (``/tracked``: the tracker, ``cnc_contour_control/disturbance/tracking.py``,
  redesigns H on a 0.5 % grid within ±10 % of the commanded speed); the full bench also at the band's ends
  with the plant's PI loops at ±20 % inertia (the model off, so the residual carries (P − P_n) v too);
- design (:func:`.bench.band_entry`): each stack designed for 1500 rpm · (1 + δ) over the tracked band, each axis with
  its own model, the plant's inertia −20 %, nominal, +20 %: |S|∞ (max |e/r|), the disturbance peak, stability.
  The tracker moves the design slowly (its estimate averages over 0.1 s), so the loop is one of these frozen
  linear loops at any time.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from cnc_tools.analysis.tables import format_table, goal_text
from cnc_tools.reproductions.paper002 import data
from cnc_tools.reproductions.paper002.cases import Plan
from cnc_tools.reproductions.paper002.runs import METHODS, Result

Results = Mapping[str, Result]
#: The goal: >= this share of the f_d line removed at every deviation within ±7 %, |S|∞ <= GOAL_PEAK.
GOAL_TRACKED_REMOVAL = 0.90


def band_items(plan: Plan, points: int) -> list[tuple[str, float, str, int]]:
    """The design items of :func:`.bench.band_entry` for the plan (every stack, band point and axis)."""
    return [(law, deviation, axis, points) for law in plan.track_laws for deviation in plan.track_band
            for axis in ("x", "y")]


def _removal(results: Results, key: str, bare_key: str) -> float | None:
    found, bare = results.get(key), results.get(bare_key)
    return None if found is None or bare is None else 1.0 - found.measure.fd_pulse / bare.measure.fd_pulse


def rows(results: Results, band: Sequence[Mapping[str, Any]], plan: Plan) -> list[dict[str, Any]]:
    """Per PDC stack: removal per deviation at the design and tracking; the band's worst loop figures; the goal."""
    out = []
    for law in plan.track_laws:
        groups = {d: f"tracked{100 * d:+.0f}%" for d in plan.track_deviations}
        held = {d: _removal(results, f"{g}/{law}", f"{g}/p") for d, g in groups.items()}
        tracked = {d: _removal(results, f"{g}/{law}/tracked", f"{g}/p") for d, g in groups.items()}
        mine = [entry for entry in band if entry["law"] == law]
        peaks = {"sensitivity_peak": max(e["sensitivity_peak"] for e in mine),
                 "disturbance_peak": max(e["disturbance_peak"] for e in mine),
                 "stable": all(bool(e["stable"]) for e in mine)}
        inertia = {f"{100 * d:+.0f}%,{eps:+.1f}": _removal(results, f"tracked{100 * d:+.0f}%,inertia{eps:+.1f}/{law}"
                                                          "/tracked", f"tracked{100 * d:+.0f}%,inertia{eps:+.1f}/p")
                   for d in plan.track_deviations for eps in plan.track_inertia}
        found_inertia = [v for v in inertia.values() if v is not None]
        worst = min(v for v in [*tracked.values(), *found_inertia] if v is not None)
        met = worst >= GOAL_TRACKED_REMOVAL and peaks["stable"] and peaks["sensitivity_peak"] <= data.GOAL_PEAK
        out.append({"law": law, "label": METHODS[law], "held": held, "tracked": tracked,
                    "tracked_inertia": {k: v for k, v in inertia.items() if v is not None},
                    "worst_tracked": worst, **peaks, "met": bool(met)})
    return out


def _pct(value: float | None) -> str:
    return "-" if value is None else f"{100.0 * value:.1f} %"


def print_rows(found: Sequence[Mapping[str, Any]], plan: Plan) -> None:
    """Removal per deviation, at the design and tracking f_d on line, and the band's loop figures."""
    band = plan.track_band
    print(f"\ngoal: >= {100 * GOAL_TRACKED_REMOVAL:.0f} % of the f_d line removed for every spindle deviation "
          f"within ±7 % WITHOUT a schedule (the servo commands 1500 rpm; track_fd: f_d estimated from the PDC's "
          f"residual), |S|∞ <= {data.GOAL_PEAK:g}; circle, {plan.side_s:g} s; 'design': the PDC at its 1500 rpm "
          f"design; |S|∞, dist. peak: every design of the band {100 * band[0]:+.0f} to {100 * band[-1]:+.0f} % "
          f"({len(band)} points), both axes, inertia ±20 %")
    deviations = plan.track_deviations
    inertia = list(found[0]["tracked_inertia"]) if found else []
    header = (["stack"] + [f"{100 * d:+.0f} % design" for d in deviations]
              + [f"{100 * d:+.0f} % tracked" for d in deviations] + [f"{k} tracked" for k in inertia]
              + ["|S|∞", "dist. peak", "stable", "goal"])
    print(format_table(header, [[r["label"], *[_pct(r["held"][d]) for d in deviations],
                                 *[_pct(r["tracked"][d]) for d in deviations],
                                 *[_pct(r["tracked_inertia"].get(k)) for k in inertia], f"{r['sensitivity_peak']:.3f}",
                                 f"{r['disturbance_peak']:.3f}", "yes" if r["stable"] else "NO",
                                 goal_text(r["met"])] for r in found]))
    if inertia:
        print("  'δ,ε tracked': spindle δ off and the plant's PI loops with K_t/J / (1 + ε) (the model off by ε)")
