"""The node processes of a scenario's graph and their parameters (what the runner starts).

Which nodes: one per stage of the scenario's pipeline
(:func:`cnc_contour_control.core.stages.pipeline`), one per axis for a per-axis
stage (the servo). Their parameters: the node's configs as plain values in the
configs' own units (:func:`cnc_contour_control.core.params.config_values`), under
the names the node declares them by, from the same config classes
(:mod:`cnc_contour_control.nodes.parameters`): the algorithm's config and the
stage's run parameters (:mod:`cnc_contour_control.graph.stage_params`), built and so
validated here before any process starts. Nothing is renamed or converted on
the way but what the servo node declares differently
(:func:`~cnc_contour_control.graph.stage_params.servo_config_values`: ``axis`` and
``gains.*``). Each stage also gets the readers it waits for before it
publishes: the pipeline's readers of its per-tick outputs, plus the run's
extra readers (a recorder, a test probe).

:func:`write_params_dir` writes the parameter files and the node list that
``contour_graph.launch.py`` starts (:mod:`cnc_contour_control.graph.graph_files`).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from cnc_contour_control.core import topics
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import config_values
from cnc_contour_control.core.stages import Pipeline, Stage
from cnc_contour_control.graph.graph_files import write_manifest, write_params_file
from cnc_contour_control.graph.stage_params import (
    TIMEOUT_RANGE_S,
    CompensatorRunParams,
    EstimatorRunParams,
    InterpolatorRunParams,
    LockstepInputs,
    ServoRunParams,
    servo_config_values,
)
from cnc_plant_sim.models.plant import PLANTS
from cnc_plant_sim.run.run_params import PlantRunParams
from cnc_tools.runs.scenario import Scenario

NAMESPACE = topics.DEFAULT_NAMESPACE
#: The plant waits for the readers of ``joint_states`` under this parameter name; other stages: ``min_subscribers``.
_READER_COUNT = {"plant": "expected_subscribers"}
#: The plant waits this many stage timeouts for commands: the stage nearest a missing input reports it first.
PLANT_TIMEOUT_FACTOR = 3.0


@dataclass(frozen=True)
class NodeSpec:
    """One process of the graph: package, executable, node name, parameters."""

    package: str
    executable: str
    name: str
    parameters: Mapping[str, Any]


@dataclass(frozen=True)
class _Run:
    """What the stages' parameters are made from."""

    scenario: Scenario
    stages: Pipeline
    run_dir: Path
    input_timeout_s: float

    @property
    def program_file(self) -> Path:
        """The program the interpolator reads (written by :func:`write_program`)."""
        return self.run_dir / "program.yaml"


def graph_nodes(scenario: Scenario, run_dir: Path, extra_subscribers: int = 0,
                input_timeout_s: float = 5.0, extra_readers: Sequence[str] = ()) -> list[NodeSpec]:
    """The node processes of a scenario, its program written into ``run_dir``.

    ``extra_subscribers`` readers (a recorder, a test probe) subscribe to every
    per-tick topic besides the graph's own; each stage waits for all its
    readers before it publishes its first message, so nothing is lost at
    start-up. ``extra_readers`` names those that are nodes of the run (the
    recorder): a stage waits for them by name (``required_readers``).
    """
    write_program(scenario, run_dir)
    return graph_specs(scenario, run_dir, extra_subscribers, input_timeout_s, extra_readers)


def graph_specs(scenario: Scenario, run_dir: Path, extra_subscribers: int = 0, input_timeout_s: float = 5.0,
                extra_readers: Sequence[str] = ()) -> list[NodeSpec]:
    """:func:`graph_nodes` without writing anything: a ConfigError for a value a node would refuse."""
    run = _Run(scenario, scenario.pipeline(), run_dir, input_timeout_s)
    readers = stage_readers(run.stages)
    specs = []
    for stage in run.stages.stages:
        make = STAGE_PARAMETERS.get(stage.name)
        if make is None:
            raise ConfigError(f"stage {stage.name!r} has no node yet; stages with nodes: {sorted(STAGE_PARAMETERS)}")
        for axis, node in _nodes(stage, run.stages.axes):
            gate: dict[str, object] = {
                _READER_COUNT.get(stage.name, "min_subscribers"): len(readers[node]) + extra_subscribers}
            # an optional output switched on (the plant's tool_position, cutting_force) is read by the extra
            # subscribers and the stages that take it (the force regulator), counted: the gate names no reader
            gate.update({f"{pattern}_subscribers": extra_subscribers + len(run.stages.readers(pattern))
                         for pattern in stage.optional_outputs if pattern in run.stages.outputs_on})
            required = sorted({*readers[node], *extra_readers})
            if required:
                gate["required_readers"] = required
            specs.append(NodeSpec(stage.package, stage.executable, node, _merge(make(run, stage, node, axis), gate)))
    return specs


def _nodes(stage: Stage, axes: Sequence[str]) -> list[tuple[str | None, str]]:
    """(axis or None, node name) of each node of ``stage``."""
    if stage.per_axis:
        return list(zip(axes, stage.node_names(axes)))
    return [(None, stage.name)]


def stage_readers(stages: Pipeline) -> dict[str, list[str]]:
    """Node name -> the nodes of the pipeline that read its per-tick outputs every tick."""
    readers: dict[str, list[str]] = {}
    for stage in stages.stages:
        for axis, node in _nodes(stage, stages.axes):
            axes = stages.axes if axis is None else (axis,)
            outputs = [name for pattern in stage.outputs if topics.topic(pattern).per_tick
                       for name in topics.topic(pattern).names(axes)]
            readers[node] = sorted({reader for name in outputs for reader in stages.readers(name)})
    return readers


def _merge(*parts: Mapping[str, Any]) -> dict[str, Any]:
    """One node's parameters from several configs; a name given twice is a bug, not an override."""
    merged: dict[str, Any] = {}
    for part in parts:
        twice = sorted(set(merged) & set(part))
        if twice:
            raise ValueError(f"parameters {twice} come from two configs")
        merged.update(part)
    return merged


def _plant_parameters(run: _Run, stage: Stage, node: str, axis: str | None) -> dict[str, Any]:
    """PlantConfig (the model's own section, the wrappers switched on) and the plant's run parameters."""
    scenario = run.scenario
    plant_run = PlantRunParams(
        initial_position_m=tuple(float(v) for v in scenario.program.start_m),
        sample_time_s=scenario.sample_time_s, duration_s=scenario.duration_s, mode=scenario.mode,
        summary_file=str(run.run_dir / "summary.json"),
        command_timeout_s=PLANT_TIMEOUT_FACTOR * run.input_timeout_s,
        startup_timeout_s=max(PlantRunParams.startup_timeout_s, PLANT_TIMEOUT_FACTOR * run.input_timeout_s),
        **scenario.realtime)
    # other models' sections are None: the node declares only its model's
    plant = {k: v for k, v in config_values(scenario.plant).items() if v is not None}
    if not scenario.plant.faults.active:  # the node's defaults: no faults (an empty mapping is no parameter)
        del plant["faults"]
    if scenario.plant.cutting.active:  # the schedule as the two lists the node declares
        plant["cutting"] = scenario.plant.cutting.values()
    else:
        del plant["cutting"]
    if not scenario.plant.periodic_load.active:  # the node's defaults: no load
        del plant["periodic_load"]
    for section in (plant[PLANTS[scenario.plant.model].section], plant.get("periodic_load", {})):
        for key in [k for k, v in section.items() if isinstance(v, (list, tuple)) and not v]:
            del section[key]  # an empty list is the node's default, and no typed parameter (rcl cannot type it)
    return _merge(plant, config_values(plant_run))


def _interpolator_parameters(run: _Run, stage: Stage, node: str, axis: str | None) -> dict[str, Any]:
    """InterpolatorConfig, AxisLimits (m/s, m/s^2), the override (``feed_override.*``) and the run parameters."""
    scenario = run.scenario
    interpolator_run = InterpolatorRunParams(axes=scenario.axes, program_file=str(run.program_file),
                                             feed_override_source=scenario.override_source,
                                             # a missing override is reported before the servos' "no reference"
                                             feed_override_timeout_s=max(TIMEOUT_RANGE_S[0], 0.5 * run.input_timeout_s))
    override = {k: v for k, v in config_values(scenario.override_config).items() if v != []}  # rcl: no empty lists
    machine = {**(config_values(scenario.travel) if scenario.travel.active else {}),
               **(config_values(scenario.homing) if scenario.raw.get("homing") is not None else {})}
    return _merge(config_values(interpolator_run), config_values(scenario.interpolator),
                  {k: v for k, v in config_values(scenario.limits).items() if v is not None},  # no jerk: unset
                  {"feed_override": override} if scenario.override_active else {},
                  {k: v for k, v in machine.items() if v != []})


def _servo_parameters(run: _Run, stage: Stage, node: str, axis: str | None) -> dict[str, Any]:
    """One axis's ServoConfig (law params as ``gains``) and the servo's run parameters."""
    scenario = run.scenario
    config = scenario.servos[scenario.axes.index(str(axis))]
    inputs = run.stages.node_inputs(stage)[node]
    servo_run = ServoRunParams(axis=config.axis_name, sample_time_s=scenario.sample_time_s,
                               use_compensation=topics.COMPENSATION.name in inputs,
                               input_timeout_s=run.input_timeout_s,
                               startup_timeout_s=max(ServoRunParams.startup_timeout_s, run.input_timeout_s))
    servo = {k: v for k, v in servo_config_values(config).items() if v != []}  # rcl: no empty lists (no schedule)
    travel_axes = scenario.travel.travel_axes
    travel = {"travel_mm": list(scenario.travel.limit_mm(str(axis)))} if str(axis) in travel_axes else {}
    return _merge(config_values(servo_run), servo, travel)


def _timeouts(run: _Run, cls: type) -> dict[str, float]:
    return {"input_timeout_s": run.input_timeout_s,
            "startup_timeout_s": max(cls.startup_timeout_s, run.input_timeout_s)}  # type: ignore[attr-defined]  # every node class has it


def _estimator_parameters(run: _Run, stage: Stage, node: str, axis: str | None) -> dict[str, Any]:
    """EstimatorSettings (method, ``params.*``) and the estimator's run parameters."""
    scenario = run.scenario
    assert scenario.estimator is not None  # the stage runs only with the section
    estimator_run = EstimatorRunParams(axes=scenario.axes, program_file=str(run.program_file),
                                       sample_time_s=scenario.sample_time_s, **_timeouts(run, EstimatorRunParams))
    return _merge(config_values(estimator_run), config_values(scenario.estimator))


def _compensator_parameters(run: _Run, stage: Stage, node: str, axis: str | None) -> dict[str, Any]:
    """CompensatorSettings (method, ``params.*``, state files) and the compensator's run parameters."""
    scenario = run.scenario
    assert scenario.compensator is not None  # the stage runs only with the section
    settings = config_values(scenario.compensator)
    for name in ("state_in", "state_out"):  # the node runs in another folder: absolute paths
        settings[name] = str(Path(settings[name]).resolve()) if settings[name] else ""
    compensator_run = CompensatorRunParams(axes=scenario.axes, command_unit=scenario.servos[0].command_unit,
                                           sample_time_s=scenario.sample_time_s,
                                           **_timeouts(run, CompensatorRunParams))
    return _merge(config_values(compensator_run), settings)


def _force_regulator_parameters(run: _Run, stage: Stage, node: str, axis: str | None) -> dict[str, Any]:
    """ForceSetpoint, ForceRegulatorConfig (the law's config as ``law_params``) and the lockstep inputs."""
    scenario = run.scenario
    assert scenario.force_regulator is not None  # the stage runs only with the section
    inputs = LockstepInputs(sample_time_s=scenario.sample_time_s, **_timeouts(run, LockstepInputs))
    return _merge(config_values(inputs), scenario.force_regulator.values())


#: Stage name -> (run, stage, node name, axis or None) -> the node's parameters.
STAGE_PARAMETERS: dict[str, Callable[[_Run, Stage, str, str | None], dict[str, Any]]] = {
    "plant": _plant_parameters,
    "interpolator": _interpolator_parameters,
    "estimator": _estimator_parameters,
    "compensator": _compensator_parameters,
    "servo": _servo_parameters,
    "force_regulator": _force_regulator_parameters,
}


def write_program(scenario: Scenario, run_dir: Path) -> Path:
    """The scenario's program section as ``run_dir/program.yaml`` (a G-code file's path made absolute)."""
    program = {"name": scenario.name, **dict(scenario.raw["program"])}
    if "gcode_file" in program and scenario.source is not None:
        program["gcode_file"] = str((scenario.source.parent / program["gcode_file"]).resolve())
    path = run_dir / "program.yaml"
    run_dir.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump({"program": program}))
    return path


def recorder_spec(scenario: Scenario, bag_path: Path) -> NodeSpec:
    """The recorder of a run: every topic of the graph, into ``bag_path``."""
    parameters: dict[str, Any] = {"output": str(bag_path), "axes": list(scenario.axes), "latched_first": True}
    if scenario.optional_stages:
        parameters["optional_stages"] = list(scenario.optional_stages)
    outputs_on = sorted(scenario.pipeline().outputs_on)
    if outputs_on:
        parameters["optional_outputs"] = outputs_on
    return NodeSpec("cnc_tools", "recorder", "recorder", parameters)


def write_params_dir(nodes: Sequence[NodeSpec], folder: Path, namespace: str = NAMESPACE, files: bool = True) -> Path:
    """Write ``graph.yaml`` into ``folder`` (the node list the launch file starts); return its path.

    Each node's parameters file is written too, unless ``files`` is False
    (the runner writes them as it starts each node, with the same function).
    """
    folder.mkdir(parents=True, exist_ok=True)
    for spec in nodes if files else ():
        write_params_file(folder, namespace, spec.name, spec.parameters)
    return write_manifest(folder, namespace, [(spec.package, spec.executable, spec.name) for spec in nodes])
