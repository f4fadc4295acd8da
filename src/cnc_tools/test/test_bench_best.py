"""Bench ``best``: the contenders' files run the paper's own case, the goals are judged right, paper 000's hold."""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest
import yaml

from cnc_tools.bench.best import (
    CONTOURS,
    Contender,
    Contour,
    Outcome,
    judge,
    judge_contour,
    measure,
    report,
    run_contender,
)
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import load_scenario

#: Keys a contender may change against the paper's PID scenario: the stack, its name and description.
STACK_KEYS = frozenset({"name", "description", "servo", "estimator", "compensator", "interpolator"})
#: Plant keys of a stack: the velocity loop's gains (paper 003's K1, K2).
STACK_PLANT_GAINS = frozenset({"ki", "kp"})


def case_of(path: str) -> dict[str, Any]:
    """The scenario file's mapping without its stack: the plant (gains aside), program, limits, timing, seed."""
    raw = yaml.safe_load((project_root() / path).read_text())
    case = {key: value for key, value in raw.items() if key not in STACK_KEYS}
    overrides = case.get("plant", {}).pop("axis_overrides", {})
    kept = {axis: {k: v for k, v in values.items() if k not in STACK_PLANT_GAINS} for axis, values in overrides.items()}
    if any(kept.values()):
        case["plant"]["axis_overrides"] = kept
    return case


@pytest.mark.parametrize("contour", CONTOURS, ids=lambda c: c.key[:3])
def test_every_contender_runs_the_paper_case_of_its_pid(contour: Contour) -> None:
    """A best file copies its paper's plant, disturbance, program and limits: if they change there, it must follow."""
    for contender in (contour.paper, contour.ours):
        assert case_of(contender.scenario) == case_of(contour.pid.scenario), contender.scenario
        assert load_scenario(project_root() / contender.scenario).name == contender.scenario.rsplit("/")[-1][:-5]


@pytest.mark.parametrize("ours, met", [
    (Outcome(10.0, 5.0, 3.0, 1), (True, True, True, True)),
    (Outcome(25.1, 5.0, 3.0, 1), (False, True, False, True)),   # max 50 / 25.1 < 2x; 1 - 25.1/100 < 80 %
    (Outcome(20.0, 10.1, 15.1, 1), (True, False, True, False)),  # RMS 30 / 10.1 < 3x; 1 - 15.1/100 < 85 %
])
def test_goals_are_judged_against_their_bounds(ours: Outcome, met: tuple[bool, ...]) -> None:
    pid, paper = Outcome(100.0, 60.0, 100.0, 1), Outcome(50.0, 30.0, 25.0, 1)
    assert tuple(goal.met for goal in judge(pid, paper, ours)) == met


def test_a_tuned_pid_adds_its_two_goals() -> None:
    pid, paper, ours = Outcome(100.0, 60.0, 100.0, 1), Outcome(50.0, 30.0, 25.0, 1), Outcome(10.0, 5.0, 3.0, 1)
    goals = judge(pid, paper, ours, tuned=Outcome(20.0, 10.0, 10.0, 1))
    assert [(g.name, round(g.value, 6), g.met) for g in goals[4:]] == [
        ("max reduction against the tuned PID", 0.5, False), ("mean reduction against the tuned PID", 0.7, False)]


def test_paper000_our_stack_meets_every_goal() -> None:
    """Paper 000's circle on the engine: PIDs, FLC, then 20 runs of PID + feedforward + ILC (about 1 s).

    The tuned PID's max is the tightest goal (35.5 um: ours must stay <= 7.09 um); ours reads 2.57 um.
    """
    contour = CONTOURS[0]
    outcomes = [run_contender(contender) for contender in contour.contenders]
    assert outcomes[-1].runs == contour.ours.runs == 20 and not outcomes[-1].fault
    goals = judge_contour(contour, outcomes)
    assert all(goal.met for goal in goals), goals


def test_a_faulted_contender_is_a_row_with_its_axis_time_and_reason(tmp_path: Path) -> None:
    """Our stack with a 1 um following-error trip faults on X at its second tick: the bench prints the fault in the
    stack's row, its goals read NOT met for the fault, the others stand."""
    raw = yaml.safe_load((project_root() / CONTOURS[0].ours.scenario).read_text())
    raw["servo"].update(min_ferror_m=1.0e-6, ferror_m=1.0e-6)
    path = tmp_path / "tripped.yaml"
    path.write_text(yaml.safe_dump(raw))
    contour = dataclasses.replace(CONTOURS[0], ours=Contender("ours", "tripped", str(path), 3), tuned=None)
    ours = run_contender(contour.ours)
    assert (ours.runs, ours.fault_axis, ours.fault_time_s) == (1, "x", 0.01), ours
    assert ours.fault.startswith("EngineFault: servo x: following error")
    text, figures = report([contour], [Outcome(100.0, 60.0, 100.0, 1), Outcome(50.0, 30.0, 25.0, 1), ours])
    assert "axis x, t 0.010 s: EngineFault: servo x: following error" in text
    assert [g["met"] for g in figures[contour.key]["goals"]] == [False] * 4
    assert text.count("a contender faulted") == 4


def test_paper002_misses_only_the_rms_goal_and_that_on_the_encoder() -> None:
    """Paper 002's circle on the engine (about 3 s): every goal but RMS met; with a 10x finer encoder under both
    stacks the RMS goal is met too, so the miss is the 1/2.4 um pulse's floor (the reason the bench prints)."""
    contour = next(c for c in CONTOURS if c.key.startswith("002"))
    outcomes = [run_contender(contender) for contender in contour.contenders]
    missed = [goal.name for goal in judge_contour(contour, outcomes) if not goal.met]
    assert missed == ["RMS: paper's best / ours"] == [name for name, _ in contour.misses]
    finer = {"plant": {"velocity_loop": {"encoder_pulse_m": 1.0e-6 / 24.0}}}
    paper, ours = (measure(run_engine(load_scenario(project_root() / c.scenario).variant(finer)))
                   for c in (contour.paper, contour.ours))
    assert paper[1] / ours[1] >= 3.0, (paper, ours)
