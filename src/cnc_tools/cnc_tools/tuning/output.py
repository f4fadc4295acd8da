"""A tuning run's files: the result as JSON, the convergence plot, the tuned scenario YAML, a table."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from cnc_contour_control.core.errors import CncError
from cnc_tools.analysis.tables import format_table
from cnc_tools.runs.scenario import Scenario, build_scenario, merge
from cnc_tools.tuning.problem import overrides_of
from cnc_tools.tuning.solve import TuningResult


def result_table(result: TuningResult) -> str:
    """The optimum and the constraints as aligned text."""
    rows: list[list[object]] = [[v.path, f"[{v.low:g}, {v.high:g}]", f"{x:.6g}"]
                                for v, x in zip(result.variables, result.x, strict=True)]
    lines = [format_table(["variable", "bounds", "optimum"], rows)]
    if result.constraints:
        crow = [[str(c), f"{value:.4g}",
                 "holds" if c.violation(value) == 0.0 else f"violated by {c.violation(value):.4g}"]
                for c, value in zip(result.constraints, result.constraint_values, strict=True)]
        lines.append(format_table(["constraint", "value", "status"], crow))
    status = "feasible" if result.feasible else f"INFEASIBLE: best total violation {result.violation:.4g}"
    lines.append(f"  objective {result.objective:.6g} {result.unit}, {result.evaluations} evaluations, "
                 f"{len(result.history)} generations; {status}")
    return "\n".join(lines)


def tuned_raw(scenario: Scenario, result: TuningResult) -> dict[str, Any]:
    """The scenario's mapping with the optimum written in (the name gets ``_tuned``)."""
    raw = merge(scenario.raw, overrides_of(result.variables, result.x, scenario.axes))
    raw["name"] = f"{scenario.name}_tuned"
    return raw


def load_problem(raw: dict[str, Any], scenario: Scenario) -> str:
    """Why the tuned mapping does not load as a scenario ("" when it does)."""
    try:
        build_scenario(raw, base_dir=scenario.source.parent if scenario.source else None)
    except CncError as err:
        return str(err)
    return ""


def write_scenario(scenario: Scenario, result: TuningResult, path: Path) -> tuple[Path, str]:
    """Write the tuned scenario YAML; returns the path and why it does not load ("" when it does).

    Program files stay relative to the original scenario's folder. A file that
    does not load (the analytic objective sets paper-003 plant keys that another
    plant model refuses) is still written, with the reason in its header.
    """
    raw = tuned_raw(scenario, result)
    program = raw.get("program", {})
    if isinstance(program, dict) and "gcode_file" in program and scenario.source is not None:
        program["gcode_file"] = str((scenario.source.parent / program["gcode_file"]).resolve())
    header = f"# {scenario.name} tuned by cnc-contour tune: " + ", ".join(
        f"{k} = {v:.6g}" for k, v in result.values().items()) + "\n"
    problem = load_problem(raw, scenario)
    if problem:
        header += f"# NOTE: this file does not load as a scenario: {problem}\n"
    path.write_text(header + yaml.safe_dump(raw, sort_keys=False))
    return path, problem


def result_json(result: TuningResult) -> dict[str, Any]:
    """The result as plain data."""
    return {
        "optimum": result.values(),
        "bounds": {v.path: [v.low, v.high] for v in result.variables},
        "objective": result.objective, "unit": result.unit,
        "constraints": {str(c): value for c, value in zip(result.constraints, result.constraint_values, strict=True)},
        "feasible": result.feasible, "violation": result.violation,
        "history": list(result.history), "evaluations": result.evaluations, "message": result.message,
        **result.extra,
    }


def write_plot(result: TuningResult, path: Path) -> Path:
    """The convergence plot: best objective per generation."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(range(1, len(result.history) + 1), result.history, marker="o")
    ax.set_xlabel("generation")
    ax.set_ylabel(f"best objective [{result.unit}]")
    ax.set_title("differential evolution: convergence")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_outputs(scenario: Scenario, result: TuningResult, out_dir: Path) -> dict[str, str]:
    """result.json, convergence.png and <name>_tuned.yaml in ``out_dir``: what -> path (and a note)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    json_path = out_dir / "result.json"
    json_path.write_text(json.dumps(result_json(result), indent=2) + "\n")
    tuned, problem = write_scenario(scenario, result, out_dir / f"{scenario.name}_tuned.yaml")
    note = f" (does not load as a scenario: {problem})" if problem else ""
    return {"json": str(json_path), "plot": str(write_plot(result, out_dir / "convergence.png")),
            "scenario": f"{tuned}{note}"}
