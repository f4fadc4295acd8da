"""Tier 1: the following-error trip, the e-stop latch and the per-second tick statistics (no ROS)."""
from __future__ import annotations

import pytest

from cnc_contour_control.axis.safety import EstopLatch, FollowingErrorLimit, check_following_error, limit_of
from cnc_contour_control.axis.servo import NO_FERROR_TRIP, ServoConfig
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.tick_stats import TickStats

LIMIT = FollowingErrorLimit("x", min_ferror_m=1e-4, ferror_m=1e-3, ferror_velocity_m_s=0.5)


@pytest.mark.parametrize(("velocity_m_s", "bound_m"), [(0.0, 1e-4), (0.5, 1.1e-3), (-0.25, 6e-4)])
def test_bound_grows_linearly_with_the_reference_speed(velocity_m_s: float, bound_m: float) -> None:
    assert LIMIT.bound_m(velocity_m_s) == pytest.approx(bound_m, rel=1e-12)


@pytest.mark.parametrize(("error_m", "tripped"), [(5.9e-4, False), (-5.9e-4, False), (6.01e-4, True),
                                                  (-6.01e-4, True)])
def test_trips_only_beyond_the_bound_in_either_direction(error_m: float, tripped: bool) -> None:
    assert LIMIT.tripped(error_m, 0.25) is tripped


def test_a_trip_is_a_fault_naming_axis_error_bound_and_tick() -> None:
    with pytest.raises(FaultError) as err:
        check_following_error(LIMIT, -2e-3, 0.25, 1_230_000_000)
    text = str(err.value)
    assert "servo x" in text and "-0.002 m" in text and "bound 0.0006 m" in text and "t=1.230000 s" in text


def test_the_trip_is_on_by_default_at_2_mm_plus_half_a_second_of_travel() -> None:
    limit = limit_of(ServoConfig(axis_name="y"))
    assert limit.active
    check_following_error(limit, 0.0019, 0.0, 0)  # within 2 mm at rest
    check_following_error(limit, 0.0069, 0.01, 0)  # within 2 mm + 0.5 s * 10 mm/s
    with pytest.raises(FaultError, match="following error 0.0071 m exceeds the bound 0.007"):
        check_following_error(limit, 0.0071, 0.01, 0)


def test_a_study_switches_the_trip_off_whatever_the_error() -> None:
    limit = limit_of(ServoConfig(axis_name="y", **NO_FERROR_TRIP))
    assert not limit.active
    check_following_error(limit, 1.0, 0.0, 0)  # no fault


def test_servo_config_carries_the_trip_and_checks_its_ranges() -> None:
    config = ServoConfig(axis_name="x", min_ferror_m=1e-4, ferror_m=1e-3, ferror_velocity_m_s=0.5)
    assert limit_of(config) == LIMIT
    with pytest.raises(ConfigError, match="ferror_m"):
        ServoConfig(axis_name="x", ferror_m=-1e-3)
    with pytest.raises(ConfigError, match="ferror_velocity_m_s"):
        ServoConfig(axis_name="x", ferror_velocity_m_s=0.0)


def test_estop_zeroes_commands_and_latches_after_the_input_clears() -> None:
    latch = EstopLatch()
    assert latch.gate([1.0, -2.0]) == [1.0, -2.0]
    assert latch.estop(True, "estop at t=0.5")
    assert not latch.estop(True, "again")  # latches once; the first cause stays
    assert latch.gate([1.0, -2.0]) == [0.0, 0.0]
    latch.estop(False, "")
    assert latch.latched and latch.gate([3.0]) == [0.0], "the latch holds after the input clears"
    assert latch.cause == "estop at t=0.5" and latch.latch_count == 1


def test_enable_refused_while_latched_with_the_cause_and_reset_only_once_the_cause_is_gone() -> None:
    latch = EstopLatch()
    latch.estop(True, "estop at t=0.5")
    refused = latch.enable(True)
    assert not refused.accepted and "estop at t=0.5" in refused.message
    assert not latch.reset().accepted, "reset refused while the input is still true"
    latch.estop(False, "")
    assert latch.reset().accepted
    assert not latch.commands_allowed, "after a reset the machine is off until enabled"
    assert latch.enable(True).accepted and latch.gate([2.0]) == [2.0]


def test_disable_zeroes_commands_without_latching() -> None:
    latch = EstopLatch()
    assert latch.enable(False).accepted and latch.gate([1.0]) == [0.0] and not latch.latched
    assert latch.enable(True).accepted and latch.gate([1.0]) == [1.0]


def test_tick_stats_close_a_window_at_each_second_of_run_time() -> None:
    stats = TickStats()
    closed = []
    for k in range(250):  # T = 10 ms: ticks 0..249, windows close at t = 1 s and 2 s
        values = stats.add(k * 10_000_000, wall_s=0.02 * k, counts={"late": (k % 4 == 0, 2)},
                           peaks={"peak_error_m": -1e-6 * k})
        if values is not None:
            closed.append(values)
    assert [v["run_time_s"] for v in closed] == ["1.000000", "2.000000"]
    first = closed[0]
    assert first["ticks"] == "101" and first["late"] == "26" and first["late_share"] == f"{26 / 202:.4f}"
    assert first["peak_error_m"] == "0.0001" and first["tick_rate_hz"] == f"{101 / 2.0:.1f}"
    assert closed[1]["ticks"] == "100" and closed[1]["peak_error_m"] == "0.0002"
