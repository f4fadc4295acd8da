"""Tier 1: one axis's reference from a joint trajectory, checked against scipy.interpolate (no ROS)."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.interpolate import CubicHermiteSpline, make_interp_spline

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.motion.trajectory_reference import (
    JointTrajectoryReference,
    ReferenceSourceParams,
    TrajectoryFollower,
)

START_NS = 2_500_000_000


def random_points(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` points at uneven, increasing times from 0.1 s on, with positions [m] and velocities [m/s]."""
    rng = np.random.default_rng(n)
    times = 0.1 + np.cumsum(rng.uniform(0.05, 0.4, n))
    return times, rng.uniform(-0.05, 0.05, n), rng.uniform(-0.2, 0.2, n)


def stamps_ns(times: np.ndarray, count: int = 397) -> np.ndarray:
    """Stamps spread over the trajectory (ends excluded), integer ns."""
    return START_NS + np.round(np.linspace(times[0], times[-1], count + 2)[1:-1] * 1e9).astype(np.int64)


@pytest.mark.parametrize("n", [2, 3, 7, 20])
def test_cubic_hermite_matches_scipy_in_position_velocity_and_acceleration(n: int) -> None:
    times, positions, velocities = random_points(n)
    reference = JointTrajectoryReference(START_NS, times, positions, velocities)
    spline = CubicHermiteSpline(times, positions, velocities)
    stamps = stamps_ns(times)
    t_s = (stamps - START_NS) / 1e9
    ours = np.array([reference.sample(int(s)) for s in stamps])
    assert reference.interpolation == "cubic_hermite"
    assert_allclose(ours[:, 0], spline(t_s), rtol=0, atol=1e-12)
    assert_allclose(ours[:, 1], spline(t_s, 1), rtol=0, atol=1e-10)
    assert_allclose(ours[:, 2], spline(t_s, 2), rtol=1e-9, atol=1e-8)


@pytest.mark.parametrize("n", [2, 5, 12])
def test_linear_without_velocities_matches_scipy(n: int) -> None:
    times, positions, _ = random_points(n)
    reference = JointTrajectoryReference(START_NS, times, positions)
    spline = make_interp_spline(times, positions, k=1)
    stamps = stamps_ns(times)
    t_s = (stamps - START_NS) / 1e9
    ours = np.array([reference.sample(int(s)) for s in stamps])
    assert reference.interpolation == "linear"
    assert_allclose(ours[:, 0], spline(t_s), rtol=0, atol=1e-12)
    assert_allclose(ours[:, 1], spline(t_s, 1), rtol=1e-9, atol=1e-12)
    assert np.all(ours[:, 2] == 0.0)


def test_the_last_point_is_held_at_rest_after_the_end() -> None:
    times, positions, velocities = [0.25, 0.5, 1.75], [0.01, -0.02, 0.03], [0.1, 0.2, 0.3]
    reference = JointTrajectoryReference(START_NS, times, positions, velocities)
    end_ns = START_NS + 1_750_000_000
    assert reference.sample(end_ns - 1_000_000)[1] != 0.0, "still moving just before the end"
    for stamp in (end_ns, end_ns + 1, end_ns + 10**10):
        assert reference.sample(stamp) == (positions[-1], 0.0, 0.0)


def test_the_follower_holds_the_measured_position_until_a_trajectory_comes() -> None:
    follower = TrajectoryFollower("x")
    assert follower.sample(0, 0.012) == (0.012, 0.0, 0.0)
    assert follower.sample(10_000_000, 0.5) == (0.012, 0.0, 0.0), "held where the first tick found the axis"


def test_a_trajectory_starting_later_begins_from_the_held_reference_without_a_step() -> None:
    follower = TrajectoryFollower("x")
    follower.sample(0, 0.01)
    follower.take(0, [1.0, 2.0], [0.03, 0.05], [0.02, 0.0])  # stamp 0: from the next sampled tick
    first = follower.sample(START_NS, 0.0)
    later = follower.sample(START_NS + 500_000_000, 0.0)
    spline = CubicHermiteSpline([0.0, 1.0, 2.0], [0.01, 0.03, 0.05], [0.0, 0.02, 0.0])
    assert first == (0.01, 0.0, pytest.approx(spline(0.0, 2)))
    assert_allclose(later, [spline(0.5), spline(0.5, 1), spline(0.5, 2)], atol=1e-12)
    assert follower.taken == 1


def test_a_stamped_trajectory_runs_from_its_stamp() -> None:
    follower = TrajectoryFollower("x")
    follower.take(START_NS, [0.0, 1.0], [0.0, 0.1])
    assert follower.sample(START_NS + 250_000_000, 0.0) == pytest.approx((0.025, 0.1, 0.0), abs=1e-15)


@pytest.mark.parametrize(("times", "positions", "velocities", "text"), [
    ([0.0, 1.0], [0.0], None, "1 positions"),
    ([], [], None, "0 times"),
    ([0.5, 0.5], [0.0, 1.0], None, "strictly increasing"),
    ([-0.1, 0.5], [0.0, 1.0], None, ">= 0"),
    ([0.0, 1.0], [0.0, float("nan")], None, "positions[1] must be finite"),
    ([0.0, 1.0], [0.0, 1.0], [0.0], "velocities has 1 values for 2 points"),
])
def test_a_bad_trajectory_is_a_fault_naming_what_is_wrong(times: list[float], positions: list[float],
                                                          velocities: list[float] | None, text: str) -> None:
    follower = TrajectoryFollower("x")
    with pytest.raises(FaultError, match=text.replace("[", r"\[").replace("]", r"\]")):
        follower.take(0, times, positions, velocities)
    assert follower.sample(0, 0.2) == (0.2, 0.0, 0.0), "the bad trajectory was never taken"


def test_reference_source_params_refuse_an_unknown_source_listing_the_valid_ones() -> None:
    assert ReferenceSourceParams().reference_source == "reference"
    with pytest.raises(ConfigError, match="reference_source.*joint_trajectory"):
        ReferenceSourceParams(reference_source="planner")
