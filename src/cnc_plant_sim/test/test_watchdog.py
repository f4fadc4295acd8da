"""Tier 1: the plant's real-time command watchdog (no ROS)."""
from __future__ import annotations

import pytest

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_plant_sim.run.run_params import PlantRunParams
from cnc_plant_sim.run.watchdog import CommandWatchdog, WatchdogParams

T_NS = 10_000_000


def test_a_late_command_is_held_until_it_is_too_old_then_zero() -> None:
    dog = CommandWatchdog(WatchdogParams(command_max_age_s=0.025), 2)
    assert dog.tick(0, [True, True], [5.0, 6.0]) == [5.0, 6.0]
    assert dog.tick(T_NS, [True, False], [5.0, 6.0]) == [5.0, 6.0], "late, held"
    assert dog.tick(2 * T_NS, [True, False], [5.0, 6.0]) == [5.0, 6.0], "20 ms old: still held"
    assert dog.tick(3 * T_NS, [True, False], [5.0, 6.0]) == [5.0, 0.0], "30 ms old: safe hold"
    assert dog.tick(4 * T_NS, [True, True], [5.0, 7.0]) == [5.0, 7.0], "fresh again"
    assert (dog.late_commands, dog.held_commands, dog.ticks) == (3, 1, 5)


def test_a_late_share_above_the_limit_faults_after_the_minimum_ticks() -> None:
    dog = CommandWatchdog(WatchdogParams(max_late_share=0.5, late_share_min_ticks=10), 1)
    for k in range(9):
        dog.tick(k * T_NS, [k % 4 == 0], [1.0])
        dog.check()  # fewer than 10 ticks: judged later
    dog.tick(9 * T_NS, [False], [1.0])
    with pytest.raises(FaultError, match=r"7 of 10 commands late \(70.0 %\).*max_late_share 0.5"):
        dog.check()


def test_a_share_at_the_limit_is_no_fault() -> None:
    dog = CommandWatchdog(WatchdogParams(max_late_share=0.5, late_share_min_ticks=2), 2)
    dog.tick(0, [True, False], [0.0, 0.0])
    dog.tick(T_NS, [False, True], [0.0, 0.0])
    assert dog.late_share == 0.5
    dog.check()


def test_the_plant_run_parameters_declare_the_watchdog_with_ranges() -> None:
    run = PlantRunParams(max_late_share=0.1, command_max_age_s=0.05)
    assert CommandWatchdog(run, 2).max_age_ns == 50_000_000
    with pytest.raises(ConfigError, match="max_late_share"):
        PlantRunParams(max_late_share=1.5)
