"""The node processes of a scenario's graph and their parameter files (what the runner starts).

One :class:`NodeSpec` per node: package, executable, node name and parameters
in the config's own units. :func:`ros_params_yaml` writes them as a ROS 2
parameters file (strings quoted, so rcl's YAML 1.1 parser keeps ``y`` a string).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from cnc_tools.runs.scenario import Scenario

NAMESPACE = "/cnc"


@dataclass(frozen=True)
class NodeSpec:
    """One process of the graph: package, executable, node name, parameters."""

    package: str
    executable: str
    name: str
    parameters: Mapping[str, Any]


def graph_nodes(scenario: Scenario, run_dir: Path, extra_subscribers: int = 0,
                input_timeout_s: float = 5.0) -> list[NodeSpec]:
    """The node processes of a scenario (plant, interpolator, one servo per axis).

    ``extra_subscribers`` readers (a recorder, a test probe) subscribe to every
    lockstep topic besides the graph's own; each stage waits for all its readers
    before it publishes its first message, so nothing is lost at start-up.
    """
    axes = list(scenario.axes)
    program_file = run_dir / "program.yaml"
    program_file.write_text(yaml.safe_dump({"program": _with_axes(scenario)}))
    servos = [_servo_spec(scenario, config, input_timeout_s, 1 + extra_subscribers) for config in scenario.servos]
    limits = scenario.limits
    interpolator = NodeSpec("cnc_contour_control", "interpolator", "interpolator", {
        "axes": axes, "program_file": str(program_file),
        "max_velocity_mm_min": [v * 60e3 for v in limits.max_velocity_m_s],
        "max_acceleration_mm_s2": [a * 1e3 for a in limits.max_acceleration_m_s2],
        "corner_angle_tolerance_deg": float(scenario.interpolator.corner_angle_tolerance_deg),
        "arc_centripetal_fraction": float(scenario.interpolator.arc_centripetal_fraction),
        "clamp_feed": scenario.interpolator.clamp_feed, "min_subscribers": len(servos) + extra_subscribers,
    })
    plant = _plant_spec(scenario, run_dir, 1 + len(servos) + extra_subscribers, input_timeout_s)
    return [plant, interpolator, *servos]


def _with_axes(scenario: Scenario) -> dict[str, Any]:
    program = {"name": scenario.name, **dict(scenario.raw["program"])}
    if "gcode_file" in program and scenario.source is not None:
        program["gcode_file"] = str((scenario.source.parent / program["gcode_file"]).resolve())
    return program


def _plant_spec(scenario: Scenario, run_dir: Path, subscribers: int, timeout_s: float) -> NodeSpec:
    plant = scenario.plant
    return NodeSpec("cnc_plant_sim", "plant", "plant", {
        "model": plant.model, "axes": list(plant.axes), "seed": int(plant.seed), "substeps": int(plant.substeps),
        "gain_variation_pct": float(plant.variation.gain_pct),
        "time_constant_variation_pct": float(plant.variation.time_constant_pct),
        "friction_variation_pct": float(plant.variation.friction_pct),
        "axis_overrides": yaml.safe_dump(dict(plant.axis_overrides)),
        "initial_position_m": [float(v) for v in scenario.program.start_m],
        "sample_time_s": float(scenario.sample_time_s), "duration_s": float(scenario.duration_s),
        "mode": scenario.mode, "expected_subscribers": subscribers,
        # Thrice the stages' timeout: the stage nearest the missing input reports it first.
        "summary_file": str(run_dir / "summary.json"), "command_timeout_s": 3.0 * float(timeout_s),
    })


def _servo_spec(scenario: Scenario, config: Any, timeout_s: float, readers: int) -> NodeSpec:
    return NodeSpec("cnc_contour_control", "servo", f"servo_{config.axis_name}", {
        "axis": config.axis_name, "sample_time_s": float(scenario.sample_time_s),
        "law": config.law, "law_params": yaml.safe_dump(dict(config.law_params), default_flow_style=True).strip(),
        "counts_per_m": float(config.counts_per_m), "ff1": float(config.ff1), "ff2": float(config.ff2),
        "output_limit": float(config.output_limit), "quantum": float(config.quantum), "command_unit": config.command_unit,
        "input_timeout_s": float(timeout_s), "min_subscribers": readers,
    })


def recorder_spec(scenario: Scenario, bag_path: Path) -> NodeSpec:
    """The recorder of a run: every topic of the graph, into ``bag_path``."""
    return NodeSpec("cnc_tools", "recorder", "recorder", {"output": str(bag_path), "axes": list(scenario.axes)})


class _QuotedDumper(yaml.SafeDumper):
    """Quotes every string, so rcl's YAML 1.1 parser never reads 'y' or 'no' as a bool."""


_QuotedDumper.add_representer(str, lambda dumper, value: dumper.represent_scalar("tag:yaml.org,2002:str", value, style='"'))


def ros_params_yaml(node: str, parameters: Mapping[str, Any]) -> str:
    """A ROS 2 parameters file for one node."""
    return yaml.dump({node: {"ros__parameters": dict(parameters)}}, Dumper=_QuotedDumper)
