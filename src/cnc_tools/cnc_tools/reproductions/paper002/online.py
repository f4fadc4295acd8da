"""The PDC redesigned on line (the servo follows the spindle speed it commands): the held ±5 % goal and the
±10 % step with its recovery time, beside the figures without redesign and with f_d tracked (no schedule,
``track_fd``: :mod:`.tracked`).

- held: the circle with the spindle held ±5 % off the 1500 rpm design; removal of the f_d line against the
  P loop, the law at its design (``/``), and following the spindle (``/online``: it redesigns at tick 0);
- step: the spindle steps ±10 % at :attr:`Plan.step_at_s`; removal at the new f_d from the step + 0.3 s
  (encoder on), and the recovery time: a lock-in over a :data:`RECOVERY_WINDOW_S` window sliding by
  :data:`RECOVERY_HOP_S` through the runs without the encoder (``/noenc``: in so short a window the
  encoder's floor, about 0.05 pulse at f_d, is as large as 10 % of the P loop's line), the time from the
  step to the end of the first window wholly after it from which every window removes >= the goal
  (:func:`~.measures.recovery_time_s`; resolution: the window).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from cnc_tools.analysis.tables import format_table, goal_text
from cnc_tools.reproductions.paper002 import data
from cnc_tools.reproductions.paper002.cases import SPINDLE_OFFSETS, Plan
from cnc_tools.reproductions.paper002.measures import recovery_time_s, sliding_lock_in
from cnc_tools.reproductions.paper002.runs import METHODS, PDC_LAWS, Result

Results = Mapping[str, Result]
#: Length of the sliding lock-in's window [s] (5.5 periods at 55 Hz) and its hop [s].
RECOVERY_WINDOW_S = 0.1
RECOVERY_HOP_S = 0.01
#: The step's goal: the f_d line back under the spindle goal's share within this time [s].
RECOVERY_GOAL_S = 1.0


def _removal(results: Results, key: str, bare_key: str) -> float | None:
    found, bare = results.get(key), results.get(bare_key)
    return None if found is None or bare is None else 1.0 - found.measure.fd_pulse / bare.measure.fd_pulse


def _pct(value: float | None) -> str:
    return "-" if value is None else f"{100.0 * value:.1f} %"


def _seconds(value: float | None) -> str:
    if value is None:
        return "-"
    if np.isnan(value):
        return "never"
    return f"<= {value:.2f} s (1st window)" if value <= RECOVERY_WINDOW_S + 1e-9 else f"{value:.2f} s"


def held_rows(results: Results, plan: Plan) -> list[dict[str, Any]]:
    """Per PDC stack: removal with the spindle held ±5 % off the design, at the design and following it."""
    rows = []
    for law in (name for name in plan.goal_laws if name in PDC_LAWS):
        groups = {offset: f"spindle{100 * offset:+.0f}%" for offset in SPINDLE_OFFSETS}
        held = {o: _removal(results, f"{g}/{law}", f"{g}/p") for o, g in groups.items()}
        online = {o: _removal(results, f"{g}/{law}/online", f"{g}/p") for o, g in groups.items()}
        worst = min(v for v in online.values() if v is not None)
        rows.append({"law": law, "label": METHODS[law], "held": held, "online": online, "worst_online": worst,
                     "met": bool(worst >= data.GOAL_SPINDLE_REMOVAL)})
    return rows


def print_held(rows: Sequence[Mapping[str, Any]]) -> None:
    """The ±5 % goal with the PDC following the spindle on line."""
    print(f"\ngoal: >= {100 * data.GOAL_SPINDLE_REMOVAL:.0f} % with the spindle held ±"
          f"{100 * data.GOAL_SPINDLE_TOLERANCE:.0f} % off the design, the servo following the speed it commands "
          "(the PDC redesigns on line at tick 0)")
    header = ["stack"] + [f"{100 * o:+.0f} % no redesign" for o in SPINDLE_OFFSETS] + \
             [f"{100 * o:+.0f} % on line" for o in SPINDLE_OFFSETS] + ["goal (on line)"]
    print(format_table(header, [[r["label"], *[_pct(r["held"][o]) for o in SPINDLE_OFFSETS],
                                 *[_pct(r["online"][o]) for o in SPINDLE_OFFSETS], goal_text(r["met"])]
                                for r in rows]))


def step_recovery_s(results: Results, key: str, bare_key: str, step_s: float) -> float | None:
    """Recovery time [s] of run ``key`` against ``bare_key`` (both with traces) after a step at ``step_s``."""
    found, bare = results.get(key), results.get(bare_key)
    if found is None or bare is None or found.trace_t_s is None or bare.trace_t_s is None:
        return None
    lines = []
    for run in (found, bare):
        t, x = np.asarray(run.trace_t_s, float), np.asarray(run.trace_pulse, float)
        near = t >= step_s - RECOVERY_WINDOW_S
        lines.append(sliding_lock_in(t[near], x[near], run.case.f_d_hz, RECOVERY_WINDOW_S, RECOVERY_HOP_S))
    (ends, law), (_, reference) = lines
    return recovery_time_s(ends, law, reference, data.GOAL_SPINDLE_REMOVAL, step_s, RECOVERY_WINDOW_S)


def step_rows(results: Results, plan: Plan) -> list[dict[str, Any]]:
    """Per step and PDC stack: removal and recovery time without redesign and redesigned on line."""
    rows = []
    for offset in plan.step_offsets:
        group = f"step{100 * offset:+.0f}%"
        for law in (name for name in plan.step_laws if name in PDC_LAWS):
            row: dict[str, Any] = {"step": offset, "law": law, "label": METHODS[law]}
            for reading, suffix in (("design", ""), ("online", "/online"), ("tracked", "/tracked")):
                row[f"removal_{reading}"] = _removal(results, f"{group}/{law}{suffix}", f"{group}/p")
                row[f"recovery_s_{reading}"] = step_recovery_s(results, f"{group}/{law}{suffix}/noenc",
                                                               f"{group}/p/noenc", plan.step_at_s)
            recovery = row["recovery_s_online"]  # the goal is the recovery; the removal is printed beside it
            row["met"] = bool(recovery is not None and recovery <= RECOVERY_GOAL_S)
            rows.append(row)
    return rows


def print_steps(rows: Sequence[Mapping[str, Any]], plan: Plan) -> None:
    """The ±10 % step: the PDC at its design beside the PDC redesigned on line."""
    print(f"\nspindle step ±10 % at {plan.step_at_s:g} s: the PDC at its 1500 rpm design beside the PDC "
          f"redesigned on line; removal at the new f_d from the step + 0.3 s; recovery: back to >= "
          f"{100 * data.GOAL_SPINDLE_REMOVAL:.0f} % for good (sliding {1e3 * RECOVERY_WINDOW_S:g} ms lock-in, "
          f"no encoder; goal <= {RECOVERY_GOAL_S:g} s)")
    print("  tracked: no schedule, the PDC estimates f_d from its residual (track_fd, .tracked)")
    print(format_table(["step", "stack", "removed (design)", "recovery (design)", "removed (on line)",
                        "recovery (on line)", "removed (tracked)", "recovery (tracked)", "goal"],
                       [[f"{100 * r['step']:+.0f} %", r["label"], _pct(r["removal_design"]),
                         _seconds(r["recovery_s_design"]), _pct(r["removal_online"]),
                         _seconds(r["recovery_s_online"]), _pct(r["removal_tracked"]),
                         _seconds(r["recovery_s_tracked"]), goal_text(r["met"])] for r in rows]))
