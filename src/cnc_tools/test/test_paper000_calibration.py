"""Paper 000's plant calibrated to Table 5's PID column: bounds, the FLC column left out, a fit that helps."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.reproductions.paper000.calibration import (
    PidColumnObjective,
    check_variables,
    compare,
    compare_text,
    default_variables,
    fit,
    fits_fault_text,
    pid_targets,
    plant_overrides,
    shipped_point,
)
from cnc_tools.reproductions.paper000.data import TABLE5, table5_row
from cnc_tools.runs.executor import LocalExecutor
from cnc_tools.runs.faults import FaultRow
from cnc_tools.tuning.problem import DesignVariable

#: Two cases keep the objective at about 0.1 s per evaluation.
ROWS = (table5_row("circle_high"), table5_row("corner_low"))
VARIABLES = (DesignVariable("ke", 0.2, 2.0), DesignVariable("lag_s", 0.0, 0.15))


def _flc_altered(rows: tuple) -> tuple:
    return tuple(dataclasses.replace(r, max_flc_blu=10 * r.max_flc_blu, rms_flc_blu=0.1 * r.rms_flc_blu) for r in rows)


@pytest.mark.parametrize(("variable", "message"), [
    (lambda: DesignVariable("ke", 2.0, 1.0), "lower bound must be <= upper bound, got 2.0 > 1.0"),
    (lambda: check_variables([DesignVariable("ke", 0.0, 1.0)]), "ke: lower bound must be > 0 count/BLU, got 0"),
    (lambda: check_variables([DesignVariable("lag_s", -0.01, 0.1)]), "lag_s: lower bound must be >= 0 s, got -0.01"),
    (lambda: check_variables([DesignVariable("friction_scale", 1.0, 1.0)]), "upper bound must be > lower bound"),
    (lambda: check_variables([DesignVariable("gain", 0.5, 2.0)]), "must be one of ['friction_scale', 'ke'"),
    (lambda: check_variables([DesignVariable("ke", 0.5, 2.0)] * 2), "ke is given more than once"),
])
def test_bad_bounds_and_names_are_refused_naming_the_parameter(variable, message) -> None:
    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("(", r"\(")):
        variable()


def test_parameters_set_the_scenario_keys_they_name() -> None:
    names = [v.path for v in default_variables()]
    overrides = plant_overrides(default_variables(), [0.5, 0.01, 2.0, 90.0])
    assert names == ["ke", "lag_s", "friction_scale", "saturation_dac"]
    assert overrides["servo"]["counts_per_m"] == pytest.approx(5.0e4)
    axes = overrides["plant"]["axis_overrides"]
    assert axes["x"]["time_constant_s"] == pytest.approx(0.065) and axes["y"]["time_constant_s"] == pytest.approx(0.066)
    assert axes["x"]["friction_scale"] == 2.0 and axes["y"]["command_limit_dac"] == 90.0
    assert shipped_point(default_variables()) == (1.0, 0.0, 1.0, 127.0)


def test_the_fit_never_reads_the_flc_column() -> None:
    altered = _flc_altered(TABLE5)
    assert pid_targets(altered) == pid_targets(TABLE5)
    x = np.asarray(shipped_point(VARIABLES))
    same = PidColumnObjective.of(VARIABLES, _flc_altered(ROWS))(x)
    assert same == PidColumnObjective.of(VARIABLES, ROWS)(x)
    pid_changed = (dataclasses.replace(ROWS[0], max_pid_blu=2 * ROWS[0].max_pid_blu), ROWS[1])
    assert PidColumnObjective.of(VARIABLES, pid_changed)(x) != same  # the check above could fail


def test_a_tiny_fit_is_closer_to_the_pid_column_than_the_shipped_plant() -> None:
    objective = PidColumnObjective.of(VARIABLES, ROWS)
    shipped = objective(np.asarray(shipped_point(VARIABLES)))
    with LocalExecutor(1) as executor:
        result = fit(objective, executor, seeds=(0,), maxiter=2, popsize=3)
    assert result.best.objective < shipped
    assert all(v.low <= x <= v.high for v, x in zip(VARIABLES, result.best.x))
    assert result.best.objective == pytest.approx(objective(np.asarray(result.best.x)))


def test_a_faulted_run_is_a_row_of_the_comparison_and_a_win_for_neither_law() -> None:
    """FLC with a 1 um following-error trip faults on X at its second tick: the comparison carries on, prints the
    run as a faulted row (axis, time, reason), counts it apart and pairs only the seed where both laws ran."""
    trip = {"servo": {"min_ferror_m": 1.0e-6, "ferror_m": 1.0e-6}}
    with LocalExecutor(1) as executor:
        tripped = compare(trip, (1,), executor, ["circle_high"])
        plain = compare({}, (1, 2), executor, ["circle_high"])
    fault = tripped[("circle_high", "flc")][0]
    assert isinstance(fault, FaultRow) and (fault.axis, fault.time_s) == ("x", 0.01), fault
    assert all(not isinstance(v, FaultRow) for found in plain.values() for v in found)
    mixed = {("circle_high", "pid"): plain[("circle_high", "pid")],
             ("circle_high", "flc"): [fault, plain[("circle_high", "flc")][1]]}
    text = compare_text(mixed, (1, 2), (table5_row("circle_high"),))
    assert "faulted runs (1; no figures, counted as a win for neither law):" in text
    fault_line = next(line for line in text.splitlines() if "faulted " in line and "EngineFault" in line)
    assert fault_line.split()[:4] == ["circle_high", "flc", "1", "faulted"]
    assert "axis x, t 0.010 s: EngineFault: servo x: following error" in fault_line
    rows = [line.split() for line in text.splitlines()
            if line.strip().startswith("circle_high ") and "EngineFault" not in line]
    assert len(rows) == 2 and all(row[-1] == "0/1" and row[-2] in ("0/1", "1/1") for row in rows), rows
    every_fit = fits_fault_text((2, 1), [plain, mixed], (1, 2)).splitlines()
    assert every_fit[1] == "faulted runs on the fitted plants (1; no figures, counted as a win for neither law):"
    assert every_fit[3].split()[:6] == ["DE", "seed", "1", "circle_high", "flc", "1"], every_fit
    assert fits_fault_text((2,), [plain], (1, 2)) == ""
