"""Tolerances on every goal, the core: the result matrix (complete, path, contour, goal, goal_time, cancel, e-stop,
trip, deactivate) each with its outcome and a reason naming the axis (or contour), the amount, the time and the line;
a joint trajectory with partial joints held and a cancel that stops on its path."""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from cnc_contour_control.core.errors import ProgramError
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.feed_override import OverrideConfig
from cnc_contour_control.motion.goal_tolerances import (
    AxisTolerance,
    GoalTolerances,
    ToleranceDefaults,
    resolve_tolerances,
)
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.program_goal import ProgramGoal
from cnc_contour_control.motion.program_session import OUTCOMES, ProgramSession, ProgramSessionParams
from cnc_contour_control.motion.session_scores import ProgramOutcome
from cnc_contour_control.motion.trajectory_motion import TrajectoryGoalError, TrajectoryMotion, TrajectoryPoints

AXES = ("x", "y", "z")
LIMITS = AxisLimits((0.05, 0.05, 0.05), (0.5, 0.5, 0.5))
DT_NS = 5_000_000
PROGRAM = "G1 X5 F1200\nG1 Y5\n"  # line 1 along x, line 2 along y


def session() -> ProgramSession:
    return ProgramSession(AXES, LIMITS, InterpolatorConfig(), OverrideConfig(),
                          ProgramSessionParams(program_source="action", settle_time_s=0.0,
                                               in_position_tolerance_mm=0.01, goal_time_s=0.5))


class Machine:
    """Ticks a session; the measured position is the tick's reference plus ``offset(k, reference)`` [m]."""

    def __init__(self, s: ProgramSession) -> None:
        self.s, self.k = s, 0
        self.position_m = np.zeros(len(AXES))
        self.offset: Callable[[int, np.ndarray], np.ndarray] = lambda k, ref: np.zeros(len(AXES))
        self.references: list[np.ndarray] = []

    def tick(self, owner: str = "program") -> ProgramOutcome | None:
        sample = self.s.step(self.k * DT_NS, list(self.position_m))
        self.references.append(sample.position_m.copy())
        self.position_m = sample.position_m + self.offset(self.k, sample.position_m)
        self.k += 1
        return self.s.take_outcome(owner)

    def until_outcome(self, owner: str = "program", before: Callable[[int], None] | None = None) -> ProgramOutcome:
        for i in range(20_000):
            if before is not None:
                before(i)
            outcome = self.tick(owner)
            if outcome is not None:
                return outcome
        raise AssertionError("no outcome")


def run(tolerances: GoalTolerances | None = None, offset: Callable[[int, np.ndarray], np.ndarray] | None = None,
        before: Callable[[Machine, int], None] | None = None) -> ProgramOutcome:
    machine = Machine(session())
    machine.tick()
    if offset is not None:
        machine.offset = offset
    program, live = machine.s.prepare(ProgramGoal(gcode=PROGRAM))
    machine.s.start(program, live, machine.s.tolerances(tolerances))
    return machine.until_outcome(before=None if before is None else (lambda i: before(machine, i)))


def lag_y_on_line_2(k: int, ref: np.ndarray) -> np.ndarray:
    """Axis y lags 0.3 mm while it moves (line 2), then settles."""
    return np.array([0.0, -3e-4 if 0.0 < ref[1] < 0.005 else 0.0, 0.0])


def stuck_x(k: int, ref: np.ndarray) -> np.ndarray:
    return np.array([-2e-4 if ref[0] > 0.0049 else 0.0, 0.0, 0.0])


def test_defaults_and_requests_resolve_per_axis_0_default_negative_unchecked() -> None:
    defaults = ToleranceDefaults(contour_m=0.0, path_m=1e-3, goal_m=1e-5, goal_velocity_m_s=1e-3, goal_time_s=5.0)
    tol = resolve_tolerances(GoalTolerances(contour_m=2e-4, path=(AxisTolerance("y", 5e-4), AxisTolerance("z", -1)),
                                            goal=(AxisTolerance("x", 0.0, 2e-3),), goal_time_s=0.0), AXES, defaults)
    assert tol.contour_m == 2e-4 and list(tol.path_m) == [1e-3, 5e-4, math.inf]
    assert list(tol.goal_m) == [1e-5] * 3 and list(tol.goal_velocity_m_s) == [2e-3, 1e-3, 1e-3]
    assert tol.goal_time_s == 5.0 and resolve_tolerances(GoalTolerances(), AXES, defaults).contour_m == math.inf
    with pytest.raises(ProgramError, match="path tolerance: unknown axis 'a'; the axes are"):
        resolve_tolerances(GoalTolerances(path=(AxisTolerance("a", 1e-3),)), AXES, defaults)
    with pytest.raises(ProgramError, match="goal_time_s must be finite and >= 0"):
        resolve_tolerances(GoalTolerances(goal_time_s=-1.0), AXES, defaults)


def test_the_result_codes_keep_their_numbers_and_the_violations_come_after() -> None:
    assert OUTCOMES.index("aborted") == 5
    assert OUTCOMES.index("path_tolerance_violated") == 6 and OUTCOMES.index("goal_tolerance_violated") == 7


def cancel_at(tick: int) -> Callable[[Machine, int], None]:
    def act(machine: Machine, i: int) -> None:
        if i == tick:
            assert machine.s.cancel()
    return act


def stop_machine_at(tick: int, cause: str) -> Callable[[Machine, int], None]:
    def act(machine: Machine, i: int) -> None:
        if i == tick:
            machine.s.machine_stopped(cause)
    return act


def deactivate_at(tick: int) -> Callable[[Machine, int], None]:
    def act(machine: Machine, i: int) -> None:
        if i == tick:
            assert machine.s.deactivate()
    return act


#: The matrix: (case, tolerances, measured offset, action) -> outcome, words its reason must hold.
MATRIX = [
    ("complete", None, None, None, "completed", ["every axis within its goal tolerance", "stopped"]),
    ("path tolerance", GoalTolerances(path=(AxisTolerance("y", 2e-4),)), lag_y_on_line_2, None,
     "path_tolerance_violated", ["axis y 0.30", "mm from its reference (tolerance 0.2 mm)", "G-code line 2",
                                 "stopped on the path"]),
    ("contour tolerance", GoalTolerances(contour_m=1e-4), lag_y_on_line_2, None, "path_tolerance_violated",
     ["contour 0.30", "mm from the programmed path (tolerance 0.1 mm)", "G-code line 2"]),
    ("goal tolerance", GoalTolerances(goal=(AxisTolerance("x", 1e-4),), goal_time_s=0.2), stuck_x, None,
     "goal_tolerance_violated", ["axis x 0.2000 mm from its end (tolerance 0.1 mm)", "goal_time_s 0.2",
                                 "G-code line 2"]),
    ("goal_time", None, stuck_x, None, "goal_tolerance_violated",
     ["axis x 0.2000 mm from its end (tolerance 0.01 mm)", "after the reference ended (goal_time_s 0.5)"]),
    ("cancel", None, None, cancel_at(40), "canceled", ["cancelled: stopped on the path"]),
    ("e-stop", None, None, stop_machine_at(40, "plant: e-stop pressed"), "faulted",
     ["machine stopped: plant: e-stop pressed"]),
    ("trip", None, None, stop_machine_at(40, "servo_x: following error 2.1 mm on axis x beyond 2 mm"), "faulted",
     ["axis x", "2.1 mm"]),
    ("deactivate", None, None, deactivate_at(40), "aborted", ["deactivated", "stopped on the path"]),
]


@pytest.mark.parametrize(("case", "tolerances", "offset", "action", "outcome", "words"), MATRIX,
                         ids=[row[0] for row in MATRIX])
def test_every_goal_ends_with_its_code_and_a_reason_naming_axis_amount_time_and_line(
        case: str, tolerances: GoalTolerances | None, offset: Callable[[int, np.ndarray], np.ndarray] | None,
        action: Callable[[Machine, int], None] | None, outcome: str, words: list[str]) -> None:
    result = run(tolerances, offset, action)
    assert result.outcome == outcome, result.reason
    for word in words:
        assert word in result.reason, (word, result.reason)
    if outcome in ("path_tolerance_violated", "goal_tolerance_violated"):
        assert " s" in result.reason.split(" at ", 1)[1], "the time"


def test_a_path_violation_stops_on_the_path_within_the_acceleration_limits() -> None:
    machine = Machine(session())
    machine.tick()
    machine.offset = lag_y_on_line_2
    program, live = machine.s.prepare(ProgramGoal(gcode=PROGRAM))
    machine.s.start(program, live, machine.s.tolerances(GoalTolerances(path=(AxisTolerance("y", 2e-4),))))
    outcome = machine.until_outcome()
    refs = np.array(machine.references)
    assert np.allclose(refs[:, 0][refs[:, 1] > 0], 0.005), "on line 2's path (x = 5 mm) throughout"
    accel = np.diff(refs[:, 1], 2) / (DT_NS * 1e-9) ** 2
    assert np.max(np.abs(accel)) <= 0.5 * 1.01 and refs[-1, 1] < 0.005, "decelerated, short of the end"
    assert outcome.outcome == "path_tolerance_violated"


def motion(points: TrajectoryPoints, hold: tuple[float, ...] = (0.001, 0.002, 0.003)) -> TrajectoryMotion:
    return TrajectoryMotion(AXES, points, np.array(hold), LIMITS)


def test_a_trajectory_of_two_of_three_axes_moves_them_and_holds_the_third() -> None:
    machine = Machine(session())
    machine.position_m = np.array([0.001, 0.002, 0.003])
    machine.tick("trajectory")
    points = TrajectoryPoints(("y", "x"), (0.5, 1.0), ((0.004, 0.002), (0.006, 0.004)))
    machine.s.start_motion("trajectory", motion(points, tuple(machine.position_m)))
    outcome = machine.until_outcome("trajectory")
    refs = np.array(machine.references)
    assert outcome.outcome == "completed", outcome.reason
    assert np.all(refs[:, 2] == 0.003), "z, not named, held"
    assert refs[-1, 0] == pytest.approx(0.004) and refs[-1, 1] == pytest.approx(0.006)
    k_half = round(0.5 / (DT_NS * 1e-9)) + 1
    assert refs[k_half, 1] == pytest.approx(0.004, abs=1e-9), "time_from_start honoured (the goal's first tick: 0)"


def test_a_cancelled_trajectory_decelerates_on_its_path() -> None:
    points = TrajectoryPoints(("x", "y"), (0.0, 1.0), ((0.0, 0.0), (0.04, 0.02)))
    m = motion(points, (0.0, 0.0, 0.0))
    refs = [m.step(k * DT_NS, 1.0 if k < 100 else 0.0).position_m for k in range(400)]
    arr = np.array(refs)
    assert np.allclose(arr[:, 1], arr[:, 0] / 2), "on the line y = x/2"
    assert arr[-1, 0] < 0.04 and np.allclose(arr[-20:], arr[-1]), "stopped short of the end, at rest"
    accel = np.diff(arr[:, 0], 2) / (DT_NS * 1e-9) ** 2
    assert np.max(np.abs(accel[99:])) <= 0.5 * 1.01, "within x's max_acceleration_m_s2"


@pytest.mark.parametrize(("points", "code", "words"), [
    (TrajectoryPoints(("x", "w"), (1.0,), ((0.0, 0.0),)), "invalid_joints", "joint 'w' is not an axis"),
    (TrajectoryPoints((), (1.0,), ((),)), "invalid_joints", "names no joint"),
    (TrajectoryPoints(("x",), (1.0, 0.5), ((0.0,), (0.01,))), "invalid_goal", "strictly increasing"),
    (TrajectoryPoints(("x",), (0.1,), ((0.1,),)), "invalid_goal", "beyond its max_velocity_m_s"),
    (TrajectoryPoints(("x", "y"), (1.0,), ((0.0,),)), "invalid_goal", "point 0 has 1 positions for 2 joints"),
])
def test_a_trajectory_that_cannot_be_followed_is_refused_with_its_code(points: TrajectoryPoints, code: str,
                                                                        words: str) -> None:
    with pytest.raises(TrajectoryGoalError, match=words) as err:
        motion(points)
    assert err.value.code == code


def test_a_trajectory_stamped_after_the_first_tick_holds_until_its_stamp() -> None:
    points = TrajectoryPoints(("x",), (0.5,), ((0.002,),))
    first_ns = 1_000_000_000
    m = TrajectoryMotion(AXES, points, np.zeros(3), LIMITS, stamp_ns=first_ns + 200_000_000)
    m.begin(first_ns)
    x = [float(m.step(k * DT_NS, 1.0).position_m[0]) for k in range(200)]
    assert x[:41] == [0.0] * 41, "held for the 0.2 s before its stamp"
    assert 0.0 < x[60] < 0.002 and x[140] == pytest.approx(0.002), "then 0.5 s to its point (0.7 s after the tick)"
