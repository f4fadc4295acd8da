"""The tuner: DE finds a known optimum, honours constraints, reports infeasible, refuses bad input, writes files."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.cli.main import main
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import load_scenario
from cnc_tools.tuning import paper003_model as p3
from cnc_tools.tuning.objectives import (
    AnalyticObjective,
    CircularObjective,
    check_constraints,
    constraint_values,
    model_at,
)
from cnc_tools.tuning.output import write_outputs
from cnc_tools.tuning.problem import Constraint, DesignVariable, overrides_of, parse_constraint, parse_variable
from cnc_tools.tuning.solve import solve

CIRCLE = project_root() / "scenarios" / "paper000_circle_high.yaml"
PAPER003 = project_root() / "scenarios" / "paper003_circle.yaml"
K1, K2 = "plant.axis_overrides.*.ki", "plant.axis_overrides.*.kp"


def shifted_bowl(x: np.ndarray) -> float:
    """(x0 − 1.5)² + (x1 + 0.5)²: minimum 0 at (1.5, −0.5)."""
    return float((x[0] - 1.5) ** 2 + (x[1] + 0.5) ** 2)


def sum_of(x: np.ndarray) -> list[float]:
    return [float(x[0] + x[1])]


def test_de_finds_a_known_optimum() -> None:
    variables = (DesignVariable("a", -3.0, 3.0), DesignVariable("b", -3.0, 3.0))
    result = solve(shifted_bowl, variables, maxiter=60, popsize=8, seed=3)
    np.testing.assert_allclose(result.x, (1.5, -0.5), atol=0.02)
    assert result.feasible and len(result.history) >= 1
    assert result.history[-1] <= result.history[0]


def test_constraint_is_honoured() -> None:
    """The bowl's minimum has a + b = 1; a + b >= 2 moves it along (1, 1)/√2 onto the line: (2, 0)."""
    variables = (DesignVariable("a", -3.0, 3.0), DesignVariable("b", -3.0, 3.0))
    constraint = Constraint("sum", ">=", 2.0)
    result = solve(shifted_bowl, variables, (constraint,), sum_of, maxiter=80, popsize=10, seed=3)
    assert result.feasible
    assert result.constraint_values[0] >= 2.0 - 1e-9
    np.testing.assert_allclose(result.x, (2.0, 0.0), atol=0.05)


def test_infeasible_reported_with_best_violation() -> None:
    variables = (DesignVariable("a", -1.0, 1.0), DesignVariable("b", -1.0, 1.0))
    result = solve(shifted_bowl, variables, (Constraint("sum", ">=", 5.0),), sum_of, maxiter=15, popsize=6, seed=1)
    assert not result.feasible
    assert result.violation == pytest.approx(5.0 - result.constraint_values[0])
    assert 3.0 <= result.violation < 3.5  # the box's best is a + b = 2


@pytest.mark.parametrize("text, message", [
    ("servo.law_params.kp=8:0.5", "lower bound must be <= upper bound, got 8.0 > 0.5"),
    ("servo.law_params.kp", "PATH=LO:HI"),
    ("servo.law_params.kp=a:b", "PATH=LO:HI"),
])
def test_bad_variable_text_refused(text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_variable(text)


def test_bad_constraint_text_refused() -> None:
    with pytest.raises(ConfigError, match="NAME>=BOUND"):
        parse_constraint("phase_margin_deg=45")


def test_variable_naming_no_scenario_parameter_refused() -> None:
    scenario = load_scenario(CIRCLE)
    with pytest.raises(ConfigError, match="servo.law_params.gain_nonsense"):
        CircularObjective(scenario, (DesignVariable("servo.law_params.gain_nonsense", 0.0, 1.0),))
    with pytest.raises(ConfigError, match="servo.law_params.ki names no parameter of the analytic model"):
        AnalyticObjective(scenario.raw, (DesignVariable("servo.law_params.ki", 0.0, 1.0),))
    with pytest.raises(ConfigError, match="constraint"):
        check_constraints((Constraint("overshoot_pct", "<=", 5.0),), scenario, "analytic")
    with pytest.raises(ConfigError, match="paper003 linear model"):
        check_constraints((Constraint("phase_margin_deg", ">=", 45.0),), scenario, "circular")


def test_analytic_objective_with_phase_margin_constraint() -> None:
    """Eq. 15 as an upper bound at ζ = 1.63 in the box K1 <= 100, K2 <= 2.6 lands on Table 2's optimal column."""
    variables = (DesignVariable(K1, 10.0, 100.0), DesignVariable(K2, 0.1, 2.6))
    constraints = (Constraint("phase_margin_eq15_deg", "<=", round(p3.phase_margin_eq15_deg(1.63), 2)),)
    objective = AnalyticObjective({}, variables, p3.Readings(lag="envelope", lag_form="first_order_radius"))
    result = solve(objective, variables, constraints,
                   lambda x: constraint_values(model_at({}, variables, x), constraints), maxiter=25, popsize=6, seed=1)
    model = model_at({}, variables, result.x)
    assert result.feasible
    assert model.zeta <= 1.6301
    np.testing.assert_allclose(result.x, (p3.PAPER003_TABLE["optimal"].k1, p3.PAPER003_TABLE["optimal"].k2), rtol=0.01)


def test_star_expands_over_the_axes_and_reads_the_paper003_keys() -> None:
    variables = (DesignVariable(K1, 10.0, 100.0), DesignVariable("servo.law_params.kp", 5.0, 100.0))
    assert overrides_of(variables, (50.0, 40.0), ("x", "y")) == {
        "plant": {"axis_overrides": {"x": {"ki": 50.0}, "y": {"ki": 50.0}}}, "servo": {"law_params": {"kp": 40.0}}}
    scenario = load_scenario(PAPER003)
    model = model_at(scenario.raw, variables, (50.0, 40.0))
    assert (model.k1, model.position_gain_x_1_s, model.position_gain_y_1_s) == (50.0, 40.0, 40.0)
    assert model.t_ip_s == scenario.interpolator.accel_decel.time_constant_s
    tuned = CircularObjective(scenario, variables).at((50.0, 40.0))
    assert tuned.raw["plant"]["axis_overrides"]["y"]["ki"] == 50.0


def test_tuned_scenario_loads_with_the_values(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE).variant({"program": {"radius_mm": 4}})
    variables = (DesignVariable("servo.law_params.kp", 1.0, 4.0),)
    objective = CircularObjective(scenario, variables)
    result = solve(objective, variables, maxiter=1, popsize=2, seed=0, unit="um")
    assert np.isfinite(result.objective)
    files = write_outputs(scenario, result, tmp_path)
    tuned = load_scenario(tmp_path / f"{scenario.name}_tuned.yaml")
    assert tuned.servos[0].law_params["kp"] == pytest.approx(result.x[0])
    assert (tmp_path / "convergence.png").stat().st_size > 0
    assert json.loads((tmp_path / "result.json").read_text())["optimum"]["servo.law_params.kp"] == result.x[0]
    assert "does not load" not in files["scenario"]


def test_cli_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "tune"
    code = main(["tune", str(CIRCLE), "--var", "servo.law_params.kp=1:4", "--objective", "circular",
                 "--set", "program.radius_mm=4", "--maxiter", "1", "--popsize", "2", "--workers", "1",
                 "--out", str(out)])
    assert code == 0
    tuned = yaml.safe_load(next(out.glob("*_tuned.yaml")).read_text())
    result = json.loads((out / "result.json").read_text())
    assert tuned["servo"]["law_params"]["kp"] == pytest.approx(result["optimum"]["servo.law_params.kp"])
    assert 1.0 <= tuned["servo"]["law_params"]["kp"] <= 4.0


def test_cli_infeasible_exit_code(tmp_path: Path) -> None:
    code = main(["tune", str(CIRCLE), "--var", f"{K1}=10:100", "--var", f"{K2}=0.1:2.6",
                 "--constraint", "phase_margin_eq15_deg>=89.9", "--maxiter", "3", "--popsize", "3",
                 "--out", str(tmp_path / "tune")])
    assert code == 3
    assert json.loads((tmp_path / "tune" / "result.json").read_text())["violation"] > 0.0


def test_pool_gives_the_same_result_as_one_process() -> None:
    """A generation evaluated through a pool of 2 spawned processes: the same search, the same optimum.

    The objective is SciPy's Rosenbrock function: a light module for the workers to import.
    """
    from scipy.optimize import rosen

    from cnc_tools.runs.executor import LocalExecutor

    variables = (DesignVariable("a", -3.0, 3.0), DesignVariable("b", -3.0, 3.0))
    alone = solve(rosen, variables, maxiter=3, popsize=4, seed=2)
    with LocalExecutor(2) as executor:
        pooled = solve(rosen, variables, maxiter=3, popsize=4, seed=2, executor=executor)
    assert pooled.x == alone.x and pooled.history == alone.history
