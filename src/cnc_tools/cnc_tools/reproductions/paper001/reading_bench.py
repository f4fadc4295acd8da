"""The ``paper001`` bench's network in every stable unit reading, beside the paper's changes.

Paper 001 prints no units, and two readings of Table 1 give a stable loop at
1 ms (:func:`~cnc_tools.reproductions.paper001.readings.stable_readings`: the
sampled linear loop's |z| < 1): c in mm with the PID per µm (the
reproduction's reading, a stiff loop whose error is a lightly damped start
transient) and c in m with the PID per mm (a soft loop, 4-5.5 N of friction
against 5 N/mm: the axes stick at the reversals). In each, the paper's
network (Section 2.3 as printed: 8-5-2, α 0.15, β 1, positions and previous
outputs unscaled in mm and N) learns over sessions of runs with the errors
in mm (the Tables' unit) and, where it differs, in the unit the reading gives
the PID's error; with η as printed (0.05) and 10× and 100× smaller.

Every session keeps the main tables' output guard, :data:`~.runs.OUTPUT_LIMIT_N`
(a clip far above what a converging network reaches, so it acts only on a
diverging one), except the rows of :data:`CLIPPED`, which clip at a limit the
reading's forces make a real one; the paper states none. The rows of
:data:`SEEDS` run with four seeds of the initial hidden weights as well (the
paper gives none). Each row gives the change of ε_peak and ε_ISE against that
reading's PID beside the paper's change against its PID, the spread of the
peak's change over the seeds, and whether ours reaches the paper's
(``holds``).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from cnc_tools.analysis.tables import format_table, goal_text
from cnc_tools.reproductions.paper001.data import paper_result
from cnc_tools.reproductions.paper001.readings import default_scenarios, reading_named, stable_readings
from cnc_tools.reproductions.paper001.runs import Session, SessionSpec


@dataclass(frozen=True)
class Network:
    """One network row: a label and its parameters beyond the paper's as printed (``nn-paper-mm``)."""

    key: str
    label: str
    params: Mapping[str, Any]


#: The rows in every reading; ``--quick`` runs the first.
NETWORKS: tuple[Network, ...] = (
    Network("printed", "η 0.05 (printed)", {}),
    Network("eta_0.005", "η 0.005", {"eta": 5.0e-3}),
    Network("eta_0.0005", "η 0.0005", {"eta": 5.0e-4}),
)
#: Rows only in one reading: a clip at about 3× the PID's peak command there (8.7 N on the circle), which keeps
#: η 0.005 from diverging in the friction-dominated reading; the paper states no limit.
CLIPPED: dict[str, tuple[Network, ...]] = {
    "si_plant_mm_gains": (Network("eta_0.005_clip_25", "η 0.005, outputs clipped at 25 N",
                                  {"eta": 5.0e-3, "output_limit": 25.0}),),
}
#: Seeds of the initial hidden weights per reading and row (the row's figures are seed 0's; the others give the
#: spread): the friction-dominated reading's rows that learn, where the paper's changes come nearest.
SEEDS: dict[str, dict[str, tuple[int, ...]]] = {
    "si_plant_mm_gains": {"eta_0.0005": (0, 1, 2, 3), "eta_0.005_clip_25": (0, 1, 2, 3)},
}
#: Metres per error unit of the learning law, by the reading's gain unit.
ERROR_SCALE_PER_M = {"mm": 1.0e3, "um": 1.0e6, "m": 1.0}
#: The contours, in print order.
CONTOURS = ("line", "circle")


def reading_names() -> tuple[str, ...]:
    """The stable readings' names (the circle's scenario sets the plant)."""
    return tuple(r.name for r in stable_readings(default_scenarios()["circle"]))


def networks_of(reading: str, gain_unit: str, quick: bool) -> list[tuple[str, str, dict[str, Any], tuple[int, ...]]]:
    """(key, label, params, seeds) of every network row of ``reading``: errors in mm, and in the PID's unit."""
    units = ["mm"] + ([gain_unit] if gain_unit != "mm" else [])
    rows = NETWORKS[:1] if quick else NETWORKS + CLIPPED.get(reading, ())
    seeds = SEEDS.get(reading, {}) if not quick else {}
    found = []
    for unit in units:
        label = "µm" if unit == "um" else unit
        for network in rows:
            found.append((f"{network.key}_{unit}", f"{network.label}, errors in {label}",
                          {"error_scale_per_m": ERROR_SCALE_PER_M[unit], **network.params},
                          seeds.get(network.key, (0,))))
    return found


def _seed_key(key: str, seed: int) -> str:
    """The session key of a network row with another seed (the first seed's is the row's own)."""
    return key if seed == 0 else f"{key}/seed_{seed}"


def reading_specs(checkpoints: Sequence[int], folder: str, quick: bool) -> list[SessionSpec]:
    """The PID and every network row of every stable reading, both contours; the networks run ``checkpoints[-1]``."""
    specs = []
    for name in reading_names():
        gain_unit = reading_named(name).gain_unit
        for contour in CONTOURS:
            prefix = f"readings/{name}/{contour}"
            specs.append(SessionSpec(f"{prefix}/pid", contour, "pid", 1, f"{folder}/{prefix}/pid", reading=name))
            specs += [SessionSpec(f"{prefix}/{_seed_key(key, seed)}", contour, "nn-paper-mm", checkpoints[-1],
                                  f"{folder}/{prefix}/{_seed_key(key, seed)}", params={**params, "seed": seed},
                                  reading=name)
                      for key, _, params, seeds in networks_of(name, gain_unit, quick) for seed in seeds]
    return specs


def reading_rows(sessions: Mapping[str, Session], checkpoints: Sequence[int], quick: bool) -> list[dict[str, Any]]:
    """One row per reading, contour, network and checkpoint: our changes beside the paper's, and whether they hold."""
    paper_runs = dict(zip(checkpoints, (10, 50)))
    rows = []
    for name in reading_names():
        for contour in CONTOURS:
            prefix = f"readings/{name}/{contour}"
            pid, paper_pid = sessions[f"{prefix}/pid"].at(1), paper_result(contour)
            rows.append({"reading": name, "contour": contour, "network": "pid", "label": "PID", "runs": 1,
                         "peak_mm": pid.peak_mm, "ise_mm2": pid.ise_mm2})
            for key, label, params, seeds in networks_of(name, reading_named(name).gain_unit, quick):
                session = sessions[f"{prefix}/{key}"]
                for runs in checkpoints:
                    found, paper = session.at(runs), paper_result(contour, "pid+nn", paper_runs[runs])
                    peak, ise = found.peak_mm / pid.peak_mm - 1.0, found.ise_mm2 / pid.ise_mm2 - 1.0
                    paper_peak = paper.peak_mm / paper_pid.peak_mm - 1.0
                    seeded = [sessions[f"{prefix}/{_seed_key(key, s)}"].at(runs).peak_mm / pid.peak_mm - 1.0
                              for s in seeds]
                    rows.append({"reading": name, "contour": contour, "network": key, "label": label,
                                 "params": params, "runs": found.run, "asked_runs": runs, "peak_mm": found.peak_mm,
                                 "ise_mm2": found.ise_mm2, "peak_change": peak, "ise_change": ise,
                                 "paper_peak_change": paper_peak, "paper_ise_change": paper.ise / paper_pid.ise - 1.0,
                                 "guard_trips": sum(1 for m in session.runs[:runs] if m.fault),
                                 "seeds": list(seeds), "seed_peak_changes": seeded, "holds": bool(peak <= paper_peak)})
    return rows


def _spread(row: Mapping[str, Any]) -> str:
    """Δ peak over the row's seeds as "lowest … highest", or "-" for one seed."""
    changes = row.get("seed_peak_changes", [])
    return "-" if len(changes) < 2 else f"{_pct(min(changes))} … {_pct(max(changes))}"


def _pct(value: float | None) -> str:
    return "-" if value is None or value != value else f"{100.0 * value:+.0f} %"


def print_readings(rows: Sequence[Mapping[str, Any]]) -> None:
    """The table: per stable reading and contour, the PID and the networks after each checkpoint."""
    print("\nthe network in every stable reading (sampled linear loop |z| < 1): Section 2.3 as printed "
          "(8-5-2, α 0.15, β 1, inputs in mm and N) but for η and the errors' unit; Δ against the PID of the same "
          "reading, paper Δ against the paper's PID; seeds 0-3: Δ peak over four seeds of the initial hidden weights "
          "(seed 0 is the row's); holds: our Δ peak ≤ the paper's after as many runs")
    print(format_table(
        ["reading", "contour", "network", "runs", "ε_peak", "Δ peak", "seeds 0-3", "paper Δ", "ε_ISE", "Δ ISE",
         "paper Δ", "guard trips", "holds"],
        [[r["reading"], r["contour"], r["label"], r["runs"], f"{r['peak_mm']:.4g}", _pct(r.get("peak_change")),
          _spread(r), _pct(r.get("paper_peak_change")), f"{r['ise_mm2']:.4g}", _pct(r.get("ise_change")),
          _pct(r.get("paper_ise_change")), f"{r['guard_trips']}/{r['runs']}" if "guard_trips" in r else "-",
          goal_text(r["holds"]) if "holds" in r else "-"] for r in rows]))
