"""Soft travel limits and homing, the core: exact path extents, refusals naming line, axis and excess; homing."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError, FaultError, ProgramError
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.feed_override import OverrideConfig
from cnc_contour_control.motion.gcode import parse_gcode
from cnc_contour_control.motion.homing import HomingParams, homing_program
from cnc_contour_control.motion.interpolation import Interpolator
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_contour_control.motion.program_goal import ProgramGoal
from cnc_contour_control.motion.program_session import ProgramSession, ProgramSessionParams
from cnc_contour_control.motion.trajectory_motion import TrajectoryGoalError, TrajectoryMotion, TrajectoryPoints
from cnc_contour_control.motion.trajectory_reference import JointTrajectoryReference, TrajectoryFollower
from cnc_contour_control.motion.travel import TravelLimits, check_trajectory, segment_extent_m

AXES = ("x", "y")
LIMITS = AxisLimits((0.05, 0.05), (0.5, 0.5))
DT_NS = 5_000_000


def dense_extent_m(segment) -> tuple[np.ndarray, np.ndarray]:
    points = segment.point(np.linspace(0.0, segment.length_m, 20001))
    return points.min(axis=0), points.max(axis=0)


@pytest.mark.parametrize("gcode", [
    "G2 X10 Y0 I5 J0 F600",            # half circle cw over the top
    "G3 X10 Y0 I5 J0 F600",            # half circle ccw under
    "G3 X0 Y0 I5 J0 F600",             # full circle
    "G2 X3 Y4 R5 F600",                # short arc, no extreme inside
    "G2 X3 Y4 R-5 F600",               # long arc through three extremes
    "G17 G3 X-1 Y1 Z2 I-1 J0 F600",    # helix: z linear
    "G18 G2 X2 Z0 I1 K0 F600",         # XZ plane
])
def test_an_arcs_extent_is_its_dense_samples_extent(gcode: str) -> None:
    axes = ("x", "y", "z")
    program = parse_gcode(gcode, axes, start_mm=[0.0, 0.0, 0.0])
    for segment in program.segments:
        low, high = segment_extent_m(segment)
        dense_low, dense_high = dense_extent_m(segment)
        np.testing.assert_allclose(low, dense_low, atol=1e-9)
        np.testing.assert_allclose(high, dense_high, atol=1e-9)


def test_an_arc_leaving_the_box_between_its_ends_is_refused_naming_line_axis_and_excess() -> None:
    program = parse_gcode("G1 X10 F600\nG3 X10 Y10 I0 J5\nG1 X0\n", AXES, start_mm=[0.0, 0.0])
    travel = TravelLimits.of({"x": [-1.0, 14.0], "y": [-1.0, 11.0]})  # both ends inside; the arc reaches x 15
    with pytest.raises(ProgramError, match=r"line 2 takes axis x to 15\.000000 mm, 1\.000000 mm beyond its "
                                           r"travel_max_mm 14"):
        travel.check_program(program)
    TravelLimits.of({"x": [-1.0, 15.0], "y": [-1.0, 11.0]}).check_program(program)


def test_the_planned_blends_are_checked_with_their_exact_extent() -> None:
    """The planned path (corner blends of G64 P) is what is checked; a blend's extent is its dense samples'."""
    program = parse_gcode("G64 P0.5\nG1 X10 F600\nG1 Y10\nG3 X0 Y10 I-5 J0\n", AXES, start_mm=[0.0, 0.0])
    planned = Interpolator(program, LIMITS, InterpolatorConfig()).program
    blends = [s for s in planned.segments if s not in program.segments]
    assert len(planned.segments) > len(program.segments)
    for segment in planned.segments:
        for got, dense in zip(segment_extent_m(segment), dense_extent_m(segment)):
            np.testing.assert_allclose(got, dense, atol=1e-9)
    assert blends
    TravelLimits.of({"x": [0.0, 10.0], "y": [0.0, 15.0]}).check_program(planned)
    with pytest.raises(ProgramError, match=r"line 4 takes axis y to 15\.000000 mm"):
        TravelLimits.of({"x": [0.0, 10.0], "y": [0.0, 14.5]}).check_program(planned)


def test_the_message_names_the_lower_bound_and_a_segment_without_line() -> None:
    program = parse_gcode("G1 X-3 F600\n", AXES, start_mm=[0.0, 0.0])
    with pytest.raises(ProgramError, match=r"axis x to -3\.000000 mm, 1\.000000 mm beyond its travel_min_mm -2"):
        TravelLimits.of({"x": [-2.0, 5.0]}).check_program(program)


@pytest.mark.parametrize("bad, words", [
    ({"travel_axes": ("x",), "travel_min_mm": (1.0,), "travel_max_mm": (1.0,)}, "travel_min_mm must be <"),
    ({"travel_axes": ("x",), "travel_min_mm": (), "travel_max_mm": (1.0,)}, "one value per travel_axes"),
    ({"travel_axes": ("x",), "travel_min_mm": (math.inf,), "travel_max_mm": (1.0,)}, "must be finite"),
])
def test_travel_limits_refuse_bad_values_naming_them(bad: dict, words: str) -> None:
    with pytest.raises(ConfigError, match=words):
        TravelLimits(**bad)


def test_an_unknown_travel_axis_is_refused() -> None:
    with pytest.raises(ConfigError, match="travel_axes names 'z'"):
        TravelLimits.of({"z": [0.0, 1.0]}).bounds_m(AXES)


def test_hermite_extremes_between_points_are_checked() -> None:
    times, positions, velocities = [0.0, 1.0], [0.0, 0.0], [0.01, 0.0]  # overshoots to +1.48 mm between
    trajectory = JointTrajectoryReference(0, times, positions, velocities)
    peak_mm = 1e3 * max(trajectory.sample(int(t * 1e9))[0] for t in np.linspace(0, 1, 10001))
    with pytest.raises(FaultError, match=r"between point 0 and point 1 takes axis x to ([\d.]+) mm") as refused:
        check_trajectory("x", (-1.0, 1.0), times, positions, velocities)
    reached_mm = float(re.search(r"to ([\d.]+) mm", str(refused.value))[1])
    assert reached_mm == pytest.approx(peak_mm, abs=2e-6)
    check_trajectory("x", (-1.0, peak_mm + 1e-5), times, positions, velocities)
    check_trajectory("x", (-1.0, 1.0), times, positions, None)  # linear: the points are the extremes


def test_a_follower_refuses_a_trajectory_outside_and_keeps_the_one_it_had() -> None:
    follower = TrajectoryFollower("x", travel_mm=(-5.0, 5.0))
    follower.take(0, [0.1, 0.2], [0.001, 0.002])
    follower.sample(DT_NS, 0.0)
    with pytest.raises(FaultError, match=r"point 1 takes axis x to 6\.000000 mm, 1\.000000 mm beyond its "
                                         r"travel_max_mm 5"):
        follower.take(0, [0.1, 0.2], [0.001, 0.006])
    assert follower.received == 1


def session(travel: TravelLimits | None = None, homing: HomingParams | None = None) -> ProgramSession:
    return ProgramSession(AXES, LIMITS, InterpolatorConfig(), OverrideConfig(),
                          ProgramSessionParams(program_source="action", settle_time_s=0.0,
                                               in_position_tolerance_mm=0.05), travel, homing)


def run_to_outcome(s: ProgramSession, start_ns: int, position: list[float], max_ticks: int = 20000):
    stamp = start_ns
    for _ in range(max_ticks):
        stamp += DT_NS
        sample = s.step(stamp, position)
        position = list(sample.position_m)  # an ideal servo
        outcome = s.take_outcome()
        if outcome is not None:
            return outcome, position
    raise AssertionError("no outcome")


def test_a_goal_leaving_the_travel_is_refused_before_it_starts() -> None:
    s = session(TravelLimits.of({"x": [-1.0, 8.0]}))
    s.step(0, [0.0, 0.0])
    with pytest.raises(ProgramError, match=r"line 2 takes axis x to 10\.000000 mm, 2\.000000 mm beyond"):
        s.prepare(ProgramGoal(gcode="G1 X5 F600\nG1 X10\n"))
    assert not s.busy


def test_require_homing_refuses_programs_until_the_homing_completed() -> None:
    homing = HomingParams(home_position_mm=(2.0, -1.0), homing_feed_mm_min=(600.0, 300.0), require_homing=True)
    s = session(TravelLimits.of({"x": [-5.0, 50.0], "y": [-5.0, 50.0]}), homing)
    s.step(0, [0.004, 0.003])
    with pytest.raises(ProgramError, match="axis x is not homed; call home first"):
        s.reserve("part")
    assert "homing started: 2 moves" in s.home()
    with pytest.raises(ProgramError, match="busy: program 'homing'"):
        s.home()
    assert s.homed.homed == [False, False]
    outcome, position = run_to_outcome(s, 0, [0.004, 0.003])
    assert outcome.outcome == "completed" and s.homed.homed == [True, True]
    np.testing.assert_allclose(position, [0.002, -0.001], atol=1e-9)
    s.reserve("part")  # accepted now
    assert s.homed.values() == {"homed.x": "true", "homed.y": "true", "require_homing": "true"}


def test_the_homing_moves_one_axis_at_a_time_at_its_feed() -> None:
    program = homing_program(AXES, np.array([0.004, 0.003]), HomingParams((2.0, 3.0), (600.0, 300.0)))
    assert program is not None and len(program.segments) == 1  # y is at home already
    assert program.segments[0].feed_m_s == pytest.approx(0.01)
    np.testing.assert_allclose(program.end_m, [0.002, 0.003])
    assert homing_program(AXES, np.array([0.002, 0.003]), HomingParams((2.0, 3.0))) is None


def test_a_home_outside_the_travel_is_refused_naming_it() -> None:
    with pytest.raises(ConfigError, match=r"home_position_mm of axis x must be within its travel \[0, 10\] mm, "
                                          r"got 20"):
        session(TravelLimits.of({"x": [0.0, 10.0]}), HomingParams((20.0, 0.0)))


def test_a_follow_trajectory_goal_is_refused_outside_the_travel_and_before_homing() -> None:
    """FollowTrajectory's motion: a joint past its travel between points (Hermite) is an invalid goal naming the
    point, the axis and the excess; under require_homing it waits for homing like a program."""
    s = session(TravelLimits.of({"x": [-1.0, 1.0]}))
    s.step(0, [0.0, 0.0])
    points = TrajectoryPoints(("x",), (0.5, 1.5), ((0.0,), (0.0,)), ((0.01,), (0.0,)))  # reaches 1.48 mm between
    motion = TrajectoryMotion(AXES, points, np.zeros(2), LIMITS)
    with pytest.raises(TrajectoryGoalError, match=r"joint_trajectory between point 0 and point 1 takes axis x to "
                                                  r"1\.\d+ mm") as refused:
        s.start_motion("follow", motion)
    assert refused.value.code == "invalid_goal" and not s.busy
    s.start_motion("follow", TrajectoryMotion(AXES, TrajectoryPoints(("x",), (0.5,), ((0.0009,),)), np.zeros(2),
                                              LIMITS))
    assert s.busy
    homing = session(homing=HomingParams(require_homing=True))
    homing.step(0, [0.0, 0.0])
    with pytest.raises(ProgramError, match="axis x is not homed; call home first"):
        homing.start_motion("follow", motion)


@pytest.mark.parametrize("bad, words", [
    ({"home_position_mm": ("a", 0.0)}, "home_position_mm must be a list of numbers"),
    ({"home_position_mm": (math.nan, 0.0)}, "home_position_mm must be finite"),
    ({"homing_feed_mm_min": (0.0,)}, "homing_feed_mm_min must be > 0"),
    ({"require_homing": 1}, "require_homing must be"),
])
def test_homing_params_refuse_bad_values_naming_them(bad: dict, words: str) -> None:
    with pytest.raises(ConfigError, match=words):
        HomingParams(**bad)
    with pytest.raises(ConfigError, match="home_position_mm needs one value per axis"):
        HomingParams((1.0,)).position_m(AXES)
