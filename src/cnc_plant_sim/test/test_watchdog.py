"""Tier 1: the plant's real-time command watchdog (no ROS)."""
from __future__ import annotations

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

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


def test_a_stalled_second_faults_a_long_run_naming_the_axis_and_the_window() -> None:
    """A servo stopped for 1 s of a 10 s run is 10 % of the run (under max_late_share) but 100 % of a window."""
    dog = CommandWatchdog(WatchdogParams(), 2, ("x", "y"))
    stall = range(300, 400)
    with pytest.raises(FaultError, match=r"of axis x's 100 commands from t = .* late .*max_late_share_window 0.5"):
        for k in range(1000):
            dog.tick(k * T_NS, [k not in stall, True], [1.0, 1.0])
            dog.check()
    assert dog.ticks < 400, "faulted during the stall, not after the run"
    assert dog.late_share < dog.params.max_late_share


def _oracle_faults(pattern: list[list[bool]], params: WatchdogParams) -> bool:
    """Whether any prefix of ``pattern`` (late flags per tick and axis) breaks either share, by brute force."""
    n_axes = len(pattern[0])
    for end in range(1, len(pattern) + 1):
        late = sum(map(sum, pattern[:end]))
        if end >= params.late_share_min_ticks and late / (end * n_axes) > params.max_late_share:
            return True
        window = pattern[end - params.late_window_ticks:end] if end >= params.late_window_ticks else []
        if window and any(sum(row[i] for row in window) / params.late_window_ticks > params.max_late_share_window
                          for i in range(n_axes)):
            return True
    return False


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(st.booleans(), min_size=2, max_size=2), min_size=1, max_size=60),
       st.integers(1, 20), st.sampled_from([0.0, 0.25, 0.5, 0.75, 1.0]), st.sampled_from([0.25, 0.5, 1.0]))
def test_the_watchdog_faults_exactly_when_a_share_is_exceeded(pattern: list[list[bool]], window: int,
                                                               window_share: float, share: float) -> None:
    params = WatchdogParams(max_late_share=share, late_share_min_ticks=5, max_late_share_window=window_share,
                            late_window_ticks=window)
    dog = CommandWatchdog(params, 2)
    faulted = False
    try:
        for k, late in enumerate(pattern):
            dog.tick(k * T_NS, [not x for x in late], [0.0, 0.0])
            dog.check()
    except FaultError:
        faulted = True
    assert faulted == _oracle_faults(pattern, params)


def test_ticks_that_do_not_keep_the_period_fault_though_every_command_came() -> None:
    """A plant asked for 10 kHz that ticks at 3 kHz sees each command within its stretched period: the period
    itself is judged."""
    dog = CommandWatchdog(WatchdogParams(late_window_ticks=10), 1, ("x",), sample_time_s=1.0e-4)
    for k in range(9):
        dog.tick(k * 300_000, [True], [0.0])
        dog.check()  # nine ticks: the window is not full yet
    dog.tick(9 * 300_000, [True], [0.0])
    with pytest.raises(FaultError, match=r"every 0.300 ms on average, 3.00 x sample_time_s 0.1 ms.*max_period_ratio 2"):
        dog.check()
    assert dog.late_commands == 0


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.5, 4.0), min_size=2, max_size=40), st.integers(2, 12),
       st.sampled_from([0.0, 1.5, 2.0, 3.0]))
@example(periods=[1.0, 1.5], window=2, ratio=1.5)  # a mean of exactly 1.5 T: faulted when compared in float s
def test_the_period_faults_exactly_when_a_windows_mean_exceeds_the_ratio(periods: list[float], window: int,
                                                                         ratio: float) -> None:
    """Generated tick periods (in sample times): a fault iff some full window's mean period exceeds the ratio."""
    params = WatchdogParams(late_window_ticks=window, max_period_ratio=ratio)
    dog = CommandWatchdog(params, 1, sample_time_s=T_NS * 1e-9)
    stamps = [0]
    for p in periods:
        stamps.append(stamps[-1] + round(p * T_NS))
    expected = ratio > 0.0 and any((stamps[end] - stamps[end - window + 1]) / (window - 1) > ratio * T_NS
                                   for end in range(window - 1, len(stamps)))
    faulted = False
    try:
        for stamp in stamps:
            dog.tick(stamp, [True], [0.0])
            dog.check()
    except FaultError:
        faulted = True
    assert faulted == expected
