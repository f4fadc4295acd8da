"""The cases of the paper-002 bench, by section, and how much of each a plan runs.

Keys: ``<group>/<law>`` (``/ref``: the same without the periodic disturbance;
``/noenc``: without the encoder; ``/redesigned``: the PDC designed for the
plant's spindle speed; ``/online``: the servo follows the spindle speed it
commands and the PDC redesigns on line; ``/tracked``: the PDC estimates f_d on
line without a schedule). Every removal is ``1 − f_d line / the P loop's f_d
line`` within one group.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from cnc_tools.reproductions.paper002 import data
from cnc_tools.reproductions.paper002.runs import METHODS, PDC_LAWS, Case

#: The paper's five methods and our PDC alone, in print order.
LAWS: tuple[str, ...] = tuple(METHODS)
#: The contours of the main table.
CONTOURS = ("line", "circle")
#: Inertia errors of the goal runs (ε: J·(1 + ε)); 0 with the PI loops shows what the continuous form alone does.
INERTIA_ERRORS = (-data.GOAL_INERTIA_ERROR, 0.0, data.GOAL_INERTIA_ERROR)
#: Spindle offsets of the goal runs (fraction of the design's 1500 rpm).
SPINDLE_OFFSETS = (-data.GOAL_SPINDLE_TOLERANCE, data.GOAL_SPINDLE_TOLERANCE)
#: Spindle deviations of the tracking runs (fraction of the commanded 1500 rpm; the goal holds within ±7 %).
TRACK_GOAL_DEVIATIONS = (-0.07, -0.04, 0.0, 0.04, 0.07)


@dataclass(frozen=True)
class Plan:
    """How much the bench runs and where it writes (``quick``: the reduced bench of the tests)."""

    quick: bool
    out_dir: Path
    json: Path | None
    workers: int
    circle_s: float | None
    side_s: float
    sweep_hz: tuple[float, ...]
    prediction_hz: tuple[float, ...]
    step_offsets: tuple[float, ...]
    grid_points: int
    design_axes: tuple[str, ...]
    track_deviations: tuple[float, ...] = ()
    track_band: tuple[float, ...] = ()
    track_inertia: tuple[float, ...] = ()

    @property
    def goal_laws(self) -> tuple[str, ...]:
        """Laws of the inertia and spindle runs."""
        return ("p", "dob_pdc", "mbda_pdc") if self.quick else LAWS

    @property
    def sweep_laws(self) -> tuple[str, ...]:
        """Laws of the f_d sweep."""
        return ("p", "dob", "mbda_pdc") if self.quick else LAWS

    @property
    def step_laws(self) -> tuple[str, ...]:
        """Laws of the spindle-step runs."""
        return ("p", "mbda_pdc") if self.quick else ("p", *PDC_LAWS)

    @property
    def track_laws(self) -> tuple[str, ...]:
        """PDC stacks of the tracking runs (f_d estimated on line)."""
        return ("mbda_pdc",) if self.quick else PDC_LAWS

    @property
    def step_at_s(self) -> float:
        """When the spindle steps [s]."""
        return 0.4 * self.side_s


def make_plan(quick: bool, out_dir: Path, json: Path | None, workers: int) -> Plan:
    """The full bench, or the quick one (2.5-s circles, fewer laws, one sweep frequency, X's design only)."""
    if quick:
        return Plan(True, out_dir, json, workers, circle_s=2.5, side_s=2.5, sweep_hz=(100.0,),
                    prediction_hz=(100.0,), step_offsets=(0.1,), grid_points=100, design_axes=("x",),
                    track_deviations=TRACK_GOAL_DEVIATIONS[::4], track_band=TRACK_GOAL_DEVIATIONS[::4])
    sweep_hz = (20.0, 35.0, 50.0, 75.0, 100.0, 150.0, 200.0)
    return Plan(False, out_dir, json, workers, circle_s=None, side_s=10.0, sweep_hz=sweep_hz,
                prediction_hz=tuple(sorted({*sweep_hz, *(float(f) for f in range(20, 201, 10))})),
                step_offsets=(-0.1, 0.1), grid_points=1000, design_axes=("x", "y"),
                track_deviations=TRACK_GOAL_DEVIATIONS, track_band=tuple(k / 100 for k in range(-10, 11)),
                track_inertia=(-data.GOAL_INERTIA_ERROR, data.GOAL_INERTIA_ERROR))


def main_cases(plan: Plan) -> list[Case]:
    """Both contours, every law, with and without the periodic disturbance (quick: the P loop's reference only)."""
    cases = []
    for contour in CONTOURS:
        duration = plan.circle_s if contour == "circle" else None
        for law in LAWS:
            cases.append(Case(f"{contour}/{law}", contour, law, duration_s=duration, keep_trace=True))
            if law == "p" or not plan.quick:
                cases.append(Case(f"{contour}/{law}/ref", contour, law, periodic=False, duration_s=duration,
                                  keep_trace=law == "p"))
    return cases


def inertia_cases(plan: Plan) -> list[Case]:
    """The circle on the PI loops with J·(1 + ε), with and (full bench) without the encoder."""
    cases = []
    for eps in INERTIA_ERRORS:
        for law in plan.goal_laws:
            group = f"inertia{eps:+.1f}"
            cases.append(Case(f"{group}/{law}", "circle", law, inertia_error=eps, duration_s=plan.side_s))
            if not plan.quick:
                cases.append(Case(f"{group}/{law}/noenc", "circle", law, inertia_error=eps, duration_s=plan.side_s,
                                  encoder=False))
    return cases


def spindle_cases(plan: Plan) -> list[Case]:
    """The circle with the spindle held ±5 % off the design; the PDC laws also redesigned for it."""
    cases = []
    for offset in SPINDLE_OFFSETS:
        rpm, group = data.SPINDLE_RPM * (1.0 + offset), f"spindle{100 * offset:+.0f}%"
        for law in plan.goal_laws:
            cases.append(Case(f"{group}/{law}", "circle", law, plant_rpm=rpm, duration_s=plan.side_s))
            if law in PDC_LAWS:
                cases.append(Case(f"{group}/{law}/redesigned", "circle", law, plant_rpm=rpm, design_rpm=rpm,
                                  duration_s=plan.side_s))
                cases.append(Case(f"{group}/{law}/online", "circle", law, plant_rpm=rpm, duration_s=plan.side_s,
                                  follow=True))
    return cases


def sweep_cases(plan: Plan) -> list[Case]:
    """f_d from 20 to 200 Hz, every law designed for it, without the encoder (the law's own removal), and the
    P loop with the encoder but without the disturbance (the f_d line an encoder would hide the rest under)."""
    cases = []
    for f_hz in plan.sweep_hz:
        rpm, group = f_hz * 60.0 / data.FLUTES, f"sweep{f_hz:g}"
        cases += [Case(f"{group}/{law}", "circle", law, plant_rpm=rpm, design_rpm=rpm, duration_s=plan.side_s,
                       encoder=False) for law in plan.sweep_laws]
        cases.append(Case(f"{group}/p/ref", "circle", "p", periodic=False, plant_rpm=rpm, duration_s=plan.side_s))
    return cases


def step_cases(plan: Plan) -> list[Case]:
    """A spindle step of ±10 % at :attr:`Plan.step_at_s`: the laws at their 1500 rpm design, and the PDC laws
    redesigned on line (``/online``: following the schedule; ``/tracked``: estimating f_d, no schedule); each
    also without the encoder (``/noenc``: the recovery time's runs)."""
    cases = []
    for offset in plan.step_offsets:
        step, group = (plan.step_at_s, data.SPINDLE_RPM * (1.0 + offset)), f"step{100 * offset:+.0f}%"
        for law in plan.step_laws:
            for suffix in ("", "/online", "/tracked") if law in PDC_LAWS else ("",):
                key, how = f"{group}/{law}{suffix}", {"follow": suffix == "/online", "track": suffix == "/tracked"}
                cases += [Case(key, "circle", law, step=step, duration_s=plan.side_s, keep_trace=True, **how),
                          Case(f"{key}/noenc", "circle", law, step=step, duration_s=plan.side_s, keep_trace=True,
                               encoder=False, **how)]
    return cases


def track_cases(plan: Plan) -> list[Case]:
    """The circle with the plant's spindle held off the commanded 1500 rpm and no schedule: the P loop, each PDC
    stack at its 1500 rpm design, and the same estimating f_d on line (``/tracked``)."""
    cases = []
    for deviation in plan.track_deviations:
        rpm, group = data.SPINDLE_RPM * (1.0 + deviation), f"tracked{100 * deviation:+.0f}%"
        cases.append(Case(f"{group}/p", "circle", "p", plant_rpm=rpm, duration_s=plan.side_s))
        for law in plan.track_laws:
            cases += [Case(f"{group}/{law}", "circle", law, plant_rpm=rpm, duration_s=plan.side_s),
                      Case(f"{group}/{law}/tracked", "circle", law, plant_rpm=rpm, duration_s=plan.side_s, track=True)]
    for deviation in (plan.track_deviations[0], plan.track_deviations[-1]) if plan.track_inertia else ():
        rpm = data.SPINDLE_RPM * (1.0 + deviation)
        for eps in plan.track_inertia:
            group = f"tracked{100 * deviation:+.0f}%,inertia{eps:+.1f}"
            cases.append(Case(f"{group}/p", "circle", "p", plant_rpm=rpm, inertia_error=eps, duration_s=plan.side_s))
            cases += [Case(f"{group}/{law}/tracked", "circle", law, plant_rpm=rpm, inertia_error=eps,
                           duration_s=plan.side_s, track=True) for law in plan.track_laws]
    return cases


def all_cases(plan: Plan) -> list[Case]:
    """Every case of the plan, in section order."""
    return (main_cases(plan) + inertia_cases(plan) + spindle_cases(plan) + sweep_cases(plan) + step_cases(plan)
            + track_cases(plan))
