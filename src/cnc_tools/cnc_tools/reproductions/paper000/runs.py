"""Runs of the paper-000 benches: a scenario with a named controller, run and scored.

- Controllers come from :data:`CONTROLLERS` by name: ``pid`` (Eq. 14, Table 4
  gains), ``flc`` (Eqs. 3-8, Tables 1, 3, 4), ``pid+ff`` / ``flc+ff`` (the same
  plus the feedforward of :func:`feedforward_axes`) and ``flc:<rule base>``
  for every alternative rule base of ``fuzzy.RULE_BASES``.
- A run goes through the node graph (recorded to MCAP, read back) or through
  the in-process engine (:func:`cnc_tools.runs.backends.run_scenario`); both
  give the one :class:`~cnc_tools.run_record.RunRecord`, scored by the one
  scorer, :func:`cnc_tools.analysis.scoring.score_run`.
- A *view* (:data:`VIEWS`) chooses what is scored, by cutting the recorded
  run before it reaches the scorer: the paper's view (``paper``: the contour
  of Eqs. 9/10 while the reference moves) or the project's default
  (``whole_run``: the programmed contour, every sample).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.core.config import require_choice
from cnc_contour_control.core.errors import BagError
from cnc_contour_control.core.lockstep import NS_PER_S
from cnc_contour_control.core.units import M_PER_BLU_PAPER000
from cnc_contour_control.laws.fuzzy import RULE_BASES
from cnc_contour_control.motion.geometry import LineSegment, Program, Segment
from cnc_plant_sim.models.plant import PlantConfig
from cnc_tools.analysis.scoring import Score, score_run
from cnc_tools.reproductions.paper000.data import TABLE4_PID_PARAMS
from cnc_tools.run_record import RecordedRun, RunRecord
from cnc_tools.runs.backends import run_scenario
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import Scenario, load_scenario


# =========================================================================== controllers
@dataclass(frozen=True)
class Controller:
    """A servo law with its parameters, and whether the feedforward of :func:`feedforward_axes` is added."""

    name: str
    label: str
    law: str
    law_params: Mapping[str, Any]
    feedforward: bool = False


def _controllers() -> dict[str, Controller]:
    found = [Controller("pid", "PID", "pid", dict(TABLE4_PID_PARAMS)),
             Controller("flc", "FLC", "fuzzy", {}),
             Controller("pid+ff", "PID+ff", "pid", dict(TABLE4_PID_PARAMS), True),
             Controller("flc+ff", "FLC+ff", "fuzzy", {}, True)]
    found += [Controller(f"flc:{name}", f"FLC {name}", "fuzzy", {"rule_base": name})
              for name in RULE_BASES if name != "paper000"]
    return {c.name: c for c in found}


#: Controllers by name.
CONTROLLERS: dict[str, Controller] = _controllers()


def get_controller(name: str) -> Controller:
    """The controller called ``name``; an unknown name lists the valid ones."""
    require_choice("controller", name, CONTROLLERS)
    return CONTROLLERS[name]


def feedforward_axes(plant: PlantConfig) -> dict[str, dict[str, float]]:
    """Per-axis ``ff1 = 1/K`` [DAC per BLU/s] and ``ff2 = τ/K`` [DAC per BLU/s²] from the *nominal* plant.

    ``u_ff = (v + τ a)/K`` inverts K/(s(τs+1)) for the reference; the drawn
    ±5 % variation of K and τ is unknown to the controller, as on a machine.
    """
    return {axis.name: {"ff1": 1.0 / axis.gain_blu_s_per_dac,
                        "ff2": axis.time_constant_s / axis.gain_blu_s_per_dac}
            for axis in plant.nominal_axes()}


def _servo_section(raw: Mapping[str, Any], controller: Controller, plant: PlantConfig) -> dict[str, Any]:
    servo = {k: v for k, v in dict(raw.get("servo", {})).items() if k not in ("law", "law_params", "axes")}
    servo.update(law=controller.law, law_params=dict(controller.law_params))
    if controller.feedforward:
        servo["axes"] = feedforward_axes(plant)
    return servo


def scenario_for(path: Path, controller: Controller, seed: int,
                 overrides: Mapping[str, Any] | None = None) -> Scenario:
    """The scenario in ``path`` with ``overrides`` (deep-merged), ``seed`` and ``controller``'s servo law.

    The servo's law and law parameters are *replaced* (a deep merge would
    keep the PID's gains beside the FLC's parameters).
    """
    base = load_scenario(path, {**dict(overrides or {}), "seed": seed})
    return base.variant(servo=_servo_section(base.raw, controller, base.plant),
                        name=f"{base.name}_{controller.name.replace(':', '_')}_seed{seed}")


# =========================================================================== running
def engine_recorded_run(scenario: Scenario, result: RunRecord | None = None) -> RunRecord:
    """Run ``scenario`` in-process (or take its ``result``): the run record a bag of the same run gives."""
    return result if result is not None else run_engine(scenario)


def graph_recorded_run(scenario: Scenario, run_dir: Path) -> RunRecord:
    """Run ``scenario`` through the node graph, recorded to ``run_dir/bag``: the record read back from the bag."""
    return run_scenario(scenario, "graph", run_dir)


# =========================================================================== views
#: Length added to the free ends of an open contour for Eq. 9 (the whole line x = a·y), m;
#: :func:`apply_view` refuses a run that reaches beyond it.
EXTENSION_M = 0.005


@dataclass(frozen=True)
class View:
    """What is scored: the contour (``program`` or ``eq9_10``) and the window of samples."""

    name: str
    description: str
    contour: str
    window: str
    skip_start_s: float = 0.0


VIEWS: dict[str, View] = {v.name: v for v in (
    View("paper", "Eqs. 9/10 (open ends extended), while the reference moves", "eq9_10", "motion"),
    View("whole_run", "programmed contour, every sample (the project's default score)", "program", "run"),
    View("after_start", "Eqs. 9/10, while the reference moves, first 0.5 s left out", "eq9_10", "motion", 0.5),
)}


def _extend(segment: Segment, at_start: bool) -> Segment:
    if not isinstance(segment, LineSegment):
        return segment
    step = EXTENSION_M * segment.unit_vector
    return (LineSegment(segment.start_m - step, segment.end_m, segment.feed_m_s) if at_start
            else LineSegment(segment.start_m, segment.end_m + step, segment.feed_m_s))


def eq9_program(program: Program) -> Program:
    """The contour of Eqs. 9/10: an open contour's end lines extended by :data:`EXTENSION_M` (closed: unchanged).

    Eq. 9 measures the distance to the whole line x = a·y, so running past
    the end point is not a contour error; Eq. 10 is the whole circle already.
    """
    segments = list(program.segments)
    if np.allclose(segments[0].start_m, segments[-1].end_m):
        return program
    segments[0] = _extend(segments[0], at_start=True)
    segments[-1] = _extend(segments[-1], at_start=False)
    return Program(program.name, program.axis_names, tuple(segments))


def _window_ns(run: RecordedRun, view: View) -> tuple[int, int]:
    """First and last stamp [ns] the view scores."""
    stamps = run.joint_states.stamp_ns
    start, end = int(stamps[0]) + round(view.skip_start_s * NS_PER_S), int(stamps[-1])
    if view.window == "motion" and run.reference is not None:
        moving = run.reference.stamp_ns[~run.reference.done]
        end = int(moving[-1]) if moving.size else end
    return start, end


def _cut(series: Any, low_ns: int, high_ns: int) -> Any:
    keep = (series.stamp_ns >= low_ns) & (series.stamp_ns <= high_ns)
    return dataclasses.replace(series, **{f.name: getattr(series, f.name)[keep] for f in dataclasses.fields(series)
                                          if isinstance(getattr(series, f.name), np.ndarray)})


def _check_extension(program: Program, extended: Program, points: np.ndarray) -> None:
    """Refuse points (N, n_axes) that project beyond an extended free end (the extension would be too short)."""
    first, last = extended.segments[0], extended.segments[-1]
    beyond = 0
    if first is not program.segments[0]:
        beyond += int(np.sum(first.nearest(points)[1] <= 0.0))
    if last is not program.segments[-1]:
        beyond += int(np.sum(last.nearest(points)[1] >= last.length_m))
    if beyond:
        raise BagError(f"{program.name}: {beyond} samples lie beyond the {EXTENSION_M * 1e3:g} mm extension of "
                       "the contour's end lines; Eq. 9 scoring needs a longer EXTENSION_M")


def apply_view(run: RecordedRun, view: View) -> RecordedRun:
    """``run`` cut to the view's window and with the view's contour; the scorer then scores all of it."""
    low, high = _window_ns(run, view)
    joint_states = _cut(run.joint_states, low, high)
    program = run.program
    if view.contour == "eq9_10":
        program = eq9_program(run.program)
        _check_extension(run.program, program, joint_states.position_m)
    return dataclasses.replace(
        run, program=program, joint_states=joint_states,
        reference=None if run.reference is None else _cut(run.reference, low, high),
        commands={axis: _cut(series, low, high) for axis, series in run.commands.items()})


# =========================================================================== scores
@dataclass(frozen=True)
class RunScore:
    """Max and RMS contour error [BLU] of one run under each view, and where it ran."""

    scenario: str
    controller: str
    seed: int
    source: str
    max_blu: dict[str, float]
    rms_blu: dict[str, float]


def blu(score: Score) -> tuple[float, float]:
    """(max, rms) of a score's contour error in BLU."""
    values = score.contour.values_si
    return values["max"] / M_PER_BLU_PAPER000, values["rms"] / M_PER_BLU_PAPER000


def score_views(run: RecordedRun, views: Mapping[str, View] = VIEWS) -> dict[str, tuple[RecordedRun, Score]]:
    """Each view of ``run`` and its score (:func:`cnc_tools.analysis.scoring.score_run`, the project's scorer)."""
    out = {}
    for name, view in views.items():
        cut = apply_view(run, view)
        out[name] = (cut, score_run(cut, ("max", "rms")))
    return out


#: A runner: scenario -> recorded run.
Runner = Callable[[Scenario], RecordedRun]


def run_and_score(scenario: Scenario, controller: str, seed: int, source: str,
                  runner: Runner) -> tuple[RunScore, dict[str, tuple[RecordedRun, Score]]]:
    """Run ``scenario`` with ``runner`` and score every view."""
    scored = score_views(runner(scenario))
    return RunScore(scenario.name, controller, seed, source,
                    {k: blu(s)[0] for k, (_, s) in scored.items()},
                    {k: blu(s)[1] for k, (_, s) in scored.items()}), scored
