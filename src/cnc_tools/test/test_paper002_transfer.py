"""``paper002-transfer``: the PDC stacked on papers 000/001's laws removes the periodic load's f_d line."""
from __future__ import annotations

import pytest

from cnc_tools.bench.registry import BENCHES
from cnc_tools.reproductions.paper002.transfer import TARGETS, paper002_transfer_bench, run_target, scenario_for


@pytest.mark.parametrize("key", ["000-pid", "001-pid"])
def test_the_pdc_on_a_papers_own_pid_removes_most_of_the_loads_f_d_line_without_raising_s(key: str) -> None:
    found = run_target(TARGETS[key], ("law", "law+pdc"))
    assert found["law"]["fd_um"] > 0.5, "the load shows in the law's error (so the removal can fail)"
    assert found["removal"] >= 0.9
    loop = found["loop"]
    assert loop["stable"] and loop["removal_at_fd"] > 0.99
    assert loop["sensitivity_peak"] <= 1.05 * loop["sensitivity_peak_without"]


def test_each_axis_gets_its_own_model_and_the_loaded_runs_carry_the_load() -> None:
    scenario = scenario_for(TARGETS["000-pid"], "law+pdc")
    x, y = (servo.law_config() for servo in scenario.servos)
    assert x.model_numerator != y.model_numerator and x.spindle_rpm == y.spindle_rpm == 150.0
    assert scenario.plant.periodic_load.amplitude == 10.0
    assert scenario_for(TARGETS["000-pid"], "floor").plant.periodic_load.amplitude == 0.0
    assert BENCHES["paper002-transfer"] is paper002_transfer_bench
