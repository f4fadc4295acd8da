"""Bench ``best``: our best stack against each paper's best method and the PID, on each paper's benchmark contour.

For papers 000-003 three contenders run on the paper's contour, each a scenario file (``scenarios/best/``
and the shipped ones), so a user runs any of them with ``./dev run``:

- the PID as the paper tuned it (paper 000 Table 4, paper 001 Table 1, paper 002's P position loop with
  K_pp 40 /s, paper 003's standard K1, K2 with k = 30 /s), the shipped scenario; for papers 000 and 003
  also one we tuned on the circle by differential evolution (``cnc-contour tune``, the command in its file);
- the paper's best method, as we implement it (FLC, PID + network after the paper's 50 runs, MBDA + PDC,
  Table 2's optimal K1, K2);
- our best stack: any combination the suite has (feedforward, tuned gains, ILC, PDC, DOB, where the
  accel/decel sits), chosen per contour and named in its file.

A learning stack (ILC, network) runs ``runs`` times on the engine, each run from the state the last one
wrote (the machine learns the path it repeats); the last run is measured. Every run is measured the same
way: the exact contour error (distance to the program) of every joint-state sample from the first
reference to the end of the run (:func:`~cnc_tools.analysis.scoring.contour_error_series`), its maximum,
RMS and mean [µm]. The goals (issue 26): our stack at least 2x lower max and 3x lower RMS than the paper's
best method, and at least 80 % lower max and 85 % lower mean than the PID (each PID the contour has).
A contender whose run faults is a row with the fault's axis, time and reason, and the goals it takes part in
are not met; a goal the suite knows it misses prints the measured reason beside it.

Paper 004 regulates the cutting force of a turning pass through the feed override: a force loop with no
contour to compare; its figures are ``cnc-contour bench paper004``'s, and this bench prints a line saying so.

The contenders are independent, so they run through the suite's executor (``--workers N`` local
processes, ``--scheduler tcp://HOST:PORT`` a Dask cluster); each is deterministic on its own.
"""
from __future__ import annotations

import argparse
import math
import tempfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.core.units import M_PER_UM
from cnc_tools.analysis.scoring import contour_error_series
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.reproductions.paper001.runs import learning_runs
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.executor import make_executor
from cnc_tools.runs.faults import FaultRow, fault_row
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import load_scenario

#: Goals against the paper's best method: how many times lower our max and RMS must be.
GOAL_MAX_RATIO, GOAL_RMS_RATIO = 2.0, 3.0
#: Goals against the PID: the smallest reduction of the max and of the mean contour error.
GOAL_PID_MAX_REDUCTION, GOAL_PID_MEAN_REDUCTION = 0.80, 0.85
#: Learning runs of our stacks (each from the last one's state; the last is measured).
OUR_RUNS = 20
#: The paper-004 line (a force loop: no contour row).
PAPER004_NOTE = ("paper 004 (turning, cutting force regulated through a 4-bit feed override): a force loop with "
                 "no contour to compare; its figures (force overshoot, ripple, override changes) are "
                 "`cnc-contour bench paper004`'s")
#: Context printed with the goals: the reductions against a tuned PID a 2025 digital-twin MPC reports.
MPC_CONTEXT = "a 2025 digital-twin MPC reports -77.8 % max / -83.9 % mean against its tuned PID"


@dataclass(frozen=True)
class Contender:
    """One stack on one contour: its role, label, scenario file (relative to the project root) and runs."""

    role: str
    label: str
    scenario: str
    runs: int = 1


@dataclass(frozen=True)
class Contour:
    """A paper's benchmark contour, its contenders and what the paper printed [µm] (None: nothing).

    ``tuned`` (optional) is a PID we tuned on the contour with ``cnc-contour tune``; the goals against the
    PID are judged against it too. ``misses`` pairs a goal's name with why it is not met (measured, printed
    beside the goal when it is not).
    """

    key: str
    pid: Contender
    paper: Contender
    ours: Contender
    printed: str
    printed_max_um: float | None = None
    printed_rms_um: float | None = None
    tuned: Contender | None = None
    misses: tuple[tuple[str, str], ...] = ()

    @property
    def contenders(self) -> tuple[Contender, ...]:
        """PID, the tuned PID (when there is one), the paper's best method, ours."""
        return (self.pid, *((self.tuned,) if self.tuned else ()), self.paper, self.ours)


#: Why paper 002's RMS goal is not met, shown by one measurement (docs/reproduction.md, "Our best stack").
PAPER002_MISSES = (
    ("RMS: paper's best / ours", "the encoder's floor, not the loop: a perfect circle read through the 1/2.4 um "
     "pulse is RMS 0.120 um; with a 1/24 um encoder ours reads RMS 0.017 um, 12x below MBDA + PDC's 0.212"),
)


def _contours() -> tuple[Contour, ...]:
    return (
        Contour("000 circle r 20 mm, 1.3 m/min",
                Contender("pid", "PID (Table 4)", "scenarios/paper000_circle_high.yaml"),
                Contender("paper", "FLC", "scenarios/best/paper000_circle_high_flc.yaml"),
                Contender("ours", "PID (higher gains) + ff + ILC", "scenarios/best/paper000_circle_high_best.yaml",
                          OUR_RUNS),
                "Table 5 FLC: max 25.7, RMS 11.7 BLU (PID 39.9, 27.7)", 257.0, 117.0,
                Contender("tuned", "PID tuned by DE", "scenarios/best/paper000_circle_high_pid_tuned.yaml")),
        Contour("001 circle r 10 mm, 5 m/min",
                Contender("pid", "PID (Table 1)", "scenarios/paper001_circle.yaml"),
                Contender("paper", "PID + NN, 50 runs", "scenarios/paper001_circle_neural.yaml", 50),
                Contender("ours", "PID + ff + ILC", "scenarios/best/paper001_circle_best.yaml", OUR_RUNS),
                "Table 3 PID + NN after 50 runs: peak 0.0373 mm (PID 0.0724)", 37.3, None),
        Contour("002 circle r 6 mm, 120 mm/min",
                Contender("pid", "P, K_pp 40 /s", "scenarios/paper002_circle.yaml"),
                Contender("paper", "MBDA + PDC", "scenarios/best/paper002_circle_mbda_pdc.yaml"),
                Contender("ours", "DOB + PDC + ff", "scenarios/best/paper002_circle_best.yaml"),
                "no circle figure; the line's (f) MBDA + PDC: RMS 0.1802 pulse", None, 0.1802 / 2.4,
                misses=PAPER002_MISSES),
        Contour("003 circle r 10 mm, 4000 mm/min",
                Contender("pid", "P + PI, standard K1 K2", "scenarios/paper003_circle.yaml"),
                Contender("paper", "optimal K1 K2 (Table 2)", "scenarios/best/paper003_circle_optimal.yaml"),
                Contender("ours", "optimal + ff + no accel/decel after + ILC",
                          "scenarios/best/paper003_circle_best.yaml", OUR_RUNS),
                "radius reduction, mean of the 24-circle grid: optimal 90 um (standard 135)", None, None,
                Contender("tuned", "P, k tuned by DE (PM 45 deg)", "scenarios/best/paper003_circle_pid_tuned.yaml")),
    )


#: The contours, papers 000-003.
CONTOURS: tuple[Contour, ...] = _contours()


@dataclass(frozen=True)
class Outcome:
    """A contender's last run: contour error max, RMS and mean [µm], the runs made, and a fault.

    A run that faulted has NaN figures, ``fault`` its reason, ``fault_axis`` the axis the reason names ("" when
    it names none) and ``fault_time_s`` the last tick it recorded [s] (NaN when it recorded none).
    """

    max_um: float
    rms_um: float
    mean_um: float
    runs: int
    fault: str = ""
    fault_axis: str = ""
    fault_time_s: float = math.nan

    @property
    def fault_text(self) -> str:
        """The fault as a table shows it: axis, time, reason ("" when the run did not fault)."""
        return FaultRow(self.fault, self.fault_axis, self.fault_time_s).text if self.fault else ""


def fault_outcome(err: CncError, runs: int, axes: Sequence[str]) -> Outcome:
    """The outcome of run ``runs`` that ended on ``err``: its reason, the axis it names, the time it stopped at."""
    row = fault_row(err, axes)
    return Outcome(math.nan, math.nan, math.nan, runs, row.reason, row.axis, row.time_s)


def measure(record: RunRecord) -> tuple[float, float, float]:
    """Max, RMS and mean [µm] of the exact contour error from the first reference to the end of the run."""
    series, _ = contour_error_series(record)
    error_um = series.error_m / M_PER_UM
    return float(error_um.max()), float(np.sqrt(np.mean(error_um ** 2))), float(error_um.mean())


def run_contender(contender: Contender) -> Outcome:
    """Run ``contender`` on the engine ``runs`` times (state carried over); measure the last run."""
    scenario = load_scenario(project_root() / contender.scenario)
    if scenario.compensator is not None:  # the state files of the session, not the file's own
        scenario = scenario.variant({"compensator": {"state_in": "", "state_out": ""}})
    made, last = 0, None
    with tempfile.TemporaryDirectory(prefix="bench_best_") as folder:
        try:
            for _, record in learning_runs(scenario, contender.runs, Path(folder)):
                made, last = made + 1, record  # only the last run is measured (a session's records are not kept)
        except CncError as err:  # a fault is a row of the table, not the bench's end
            return fault_outcome(err, made + 1, scenario.plant.axes)
    if last is None:
        raise CncError(f"contender {contender.label!r}: runs must be >= 1, got {contender.runs}")
    return Outcome(*measure(last), made)


@dataclass(frozen=True)
class Goal:
    """One goal of a contour: its name, the figure, the bound and whether it is met."""

    name: str
    value: float
    bound: float
    met: bool


def judge(pid: Outcome, paper: Outcome, ours: Outcome, tuned: Outcome | None = None) -> tuple[Goal, ...]:
    """The goals: paper/ours max >= 2, RMS >= 3; reduction against the PID (and the tuned PID) max >= 80 %,
    mean >= 85 %."""
    def ratio(low: float, high: float) -> float:
        if not (math.isfinite(low) and math.isfinite(high)):
            return math.nan  # a contender faulted: the goal is not met
        return high / low if low > 0.0 else math.inf

    max_ratio, rms_ratio = ratio(ours.max_um, paper.max_um), ratio(ours.rms_um, paper.rms_um)
    goals = [Goal("max: paper's best / ours", max_ratio, GOAL_MAX_RATIO, max_ratio >= GOAL_MAX_RATIO),
             Goal("RMS: paper's best / ours", rms_ratio, GOAL_RMS_RATIO, rms_ratio >= GOAL_RMS_RATIO)]
    for name, base in (("the paper's PID", pid), ("the tuned PID", tuned)):
        if base is not None:
            max_cut, mean_cut = 1.0 - ours.max_um / base.max_um, 1.0 - ours.mean_um / base.mean_um
            goals += [Goal(f"max reduction against {name}", max_cut, GOAL_PID_MAX_REDUCTION,
                           max_cut >= GOAL_PID_MAX_REDUCTION),
                      Goal(f"mean reduction against {name}", mean_cut, GOAL_PID_MEAN_REDUCTION,
                           mean_cut >= GOAL_PID_MEAN_REDUCTION)]
    return tuple(goals)


def judge_contour(contour: Contour, outcomes: Sequence[Outcome]) -> tuple[Goal, ...]:
    """The goals of ``contour`` from its contenders' outcomes (in the order of ``contour.contenders``)."""
    found = {c.role: o for c, o in zip(contour.contenders, outcomes, strict=True)}
    return judge(found["pid"], found["paper"], found["ours"], found.get("tuned"))


def _number(value: float | None, digits: int = 3) -> object:
    return "—" if value is None or not math.isfinite(value) else round(value, digits)


def contender_rows(contour: Contour, outcomes: Sequence[Outcome]) -> list[list[object]]:
    """One row per contender: contour, role, stack, runs, max, RMS, mean [µm], fault."""
    pairs = zip(contour.contenders, outcomes, strict=True)
    return [[contour.key if i == 0 else "", c.role, c.label, o.runs, _number(o.max_um), _number(o.rms_um),
             _number(o.mean_um), o.fault_text] for i, (c, o) in enumerate(pairs)]


def goal_rows(contour: Contour, goals: Sequence[Goal]) -> list[list[object]]:
    """One row per goal: contour, goal, value, bound, met / NOT met, why not (a fault, or the contour's reason)."""
    def shown(goal: Goal) -> tuple[str, str]:
        if not math.isfinite(goal.value) and not goal.met:
            value = "—"
        elif "reduction" in goal.name:
            value = f"{100.0 * goal.value:.1f} %"
        else:
            value = f"{goal.value:.2f}x"
        return value, f">= {100.0 * goal.bound:.0f} %" if "reduction" in goal.name else f">= {goal.bound:g}x"

    def why(goal: Goal) -> str:
        if goal.met:
            return ""
        return "a contender faulted" if math.isnan(goal.value) else dict(contour.misses).get(goal.name, "")

    return [[contour.key if i == 0 else "", g.name, *shown(g), goal_text(g.met), why(g)] for i, g in enumerate(goals)]


def _chosen(quick: bool) -> tuple[Contour, ...]:
    """All contours, or (``--quick``) paper 000's and 003's, whose runs are shortest."""
    return tuple(c for c in CONTOURS if not quick or c.key.startswith(("000", "003")))


def best_bench(options: argparse.Namespace) -> int:
    """Run every contender, print the contour errors, the papers' figures and the goals met or not met."""
    contours = _chosen(options.quick)
    items = [contender for contour in contours for contender in contour.contenders]
    with make_executor(getattr(options, "workers", None), getattr(options, "scheduler", None)) as executor:
        outcomes = executor.map(run_contender, items, label="best")
    text, figures = report(contours, outcomes)
    print(text)
    write_json(options.json, {"bench": "best", "contours": figures, "machine": machine()})
    return 0


def report(contours: Sequence[Contour], outcomes: Sequence[Outcome]) -> tuple[str, dict[str, Any]]:
    """The bench's printout and figures from every contender's outcome (in the order of the contours' contenders).

    A faulted contender is a row with its fault (axis, time, reason); the goals it takes part in are not met.
    """
    rows: list[list[object]] = []
    goals: list[list[object]] = []
    figures: dict[str, Any] = {}
    starts = np.cumsum([0, *(len(contour.contenders) for contour in contours)])
    for index, contour in enumerate(contours):
        found = outcomes[starts[index]: starts[index + 1]]
        verdict = judge_contour(contour, found)
        rows += contender_rows(contour, found)
        goals += goal_rows(contour, verdict)
        figures[contour.key] = {"contenders": [{**asdict(c), **asdict(o)} for c, o in zip(contour.contenders, found,
                                                                                            strict=True)],
                                "goals": [asdict(g) for g in verdict], "printed": contour.printed}
    text = "\n".join([
        "contour error [µm], exact distance to the program, first reference to the end of the run "
        "(learning stacks: the last of their runs)",
        format_table(["contour", "role", "stack", "runs", "max", "RMS", "mean", "fault"], rows),
        "the papers' printed figures:", *(f"  {c.key}: {c.printed}" for c in contours),
        f"goals ({MPC_CONTEXT}):", format_table(["contour", "goal", "value", "bound", "status", "why not"], goals),
        PAPER004_NOTE])
    return text, figures
