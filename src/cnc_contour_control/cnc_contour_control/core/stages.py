"""The lockstep tick as one declared pipeline of stages (ROS-free).

One tick k, in order::

    stage          node (package executable)              inputs                         outputs
    plant          cnc_plant_sim plant                    servo/{axis}/command           joint_states, /clock
                                                                                         [tool_position, cutting_force]
    interpolator   cnc_contour_control interpolator       joint_states [feed_override]   reference, path
    estimator      cnc_contour_control estimator          joint_states, reference        contour_error
    compensator    cnc_contour_control compensator        joint_states, reference,       compensation
                                                          contour_error
    servo (1/axis) cnc_contour_control servo              joint_states, reference        servo/{axis}/command
                                                          [compensation]
    force_regulator cnc_contour_control force_regulator   cutting_force                  feed_override

The plant closes the tick: it integrates once it holds every axis's command
for the tick. The estimator reads the part program from its file, as the
interpolator does (the path estimator measures against its geometry). A stage
whose ``optional`` flag is set runs only when the scenario asks for it; an
optional *input* (in brackets) is taken only when
the stage that produces it runs; an optional *output* (in brackets) is
published only when the run switches it on (``tool_position``: a plant with
machine faults; ``cutting_force``: a plant with a cutting process). The engine steps the same list in the same
order; the runner starts one node per stage (one per axis for the servo);
the recorder and the bag reader take the per-tick topics from it.
"""
from __future__ import annotations

from collections.abc import Collection, Iterable, Sequence
from dataclasses import dataclass

from cnc_contour_control.core import topics as t
from cnc_contour_control.core.errors import ConfigError


@dataclass(frozen=True)
class Stage:
    """One stage of the tick.

    Attributes
    ----------
    name : str
        Stage name (also the node name; ``servo_<axis>`` per axis).
    package, executable : str
        What ``ros2 run`` starts.
    inputs : tuple of str
        Topic patterns (:data:`cnc_contour_control.core.topics.TOPICS` keys) the stage needs every tick.
    outputs : tuple of str
        Topic patterns it publishes.
    optional_inputs : tuple of str
        Inputs taken only when their producing stage is part of the run.
    optional_outputs : tuple of str
        Outputs published only when the run switches them on (:attr:`Pipeline.outputs_on`).
    per_axis : bool
        One node per axis.
    optional : bool
        Runs only when the scenario asks for it.
    """

    name: str
    package: str
    executable: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    optional_inputs: tuple[str, ...] = ()
    per_axis: bool = False
    optional_outputs: tuple[str, ...] = ()
    optional: bool = False

    def node_names(self, axes: Iterable[str]) -> tuple[str, ...]:
        """The node names of this stage: its name, or ``<name>_<axis>`` per axis."""
        return tuple(f"{self.name}_{a}" for a in axes) if self.per_axis else (self.name,)


PLANT = Stage("plant", "cnc_plant_sim", "plant", (t.COMMAND.name,), (t.JOINT_STATES.name, t.CLOCK.name),
              optional_outputs=(t.TOOL_POSITION.name, t.CUTTING_FORCE.name))
INTERPOLATOR = Stage("interpolator", "cnc_contour_control", "interpolator", (t.JOINT_STATES.name,),
                     (t.REFERENCE.name, t.PATH.name), optional_inputs=(t.FEED_OVERRIDE.name,))
ESTIMATOR = Stage("estimator", "cnc_contour_control", "estimator",
                  (t.JOINT_STATES.name, t.REFERENCE.name), (t.CONTOUR_ERROR.name,), optional=True)
COMPENSATOR = Stage("compensator", "cnc_contour_control", "compensator",
                    (t.JOINT_STATES.name, t.REFERENCE.name, t.CONTOUR_ERROR.name), (t.COMPENSATION.name,),
                    optional=True)
SERVO = Stage("servo", "cnc_contour_control", "servo", (t.JOINT_STATES.name, t.REFERENCE.name),
              (t.COMMAND.name,), optional_inputs=(t.COMPENSATION.name,), per_axis=True)
FORCE_REGULATOR = Stage("force_regulator", "cnc_contour_control", "force_regulator", (t.CUTTING_FORCE.name,),
                        (t.FEED_OVERRIDE.name,), optional=True)

#: Every stage, in tick order (the plant first: it opens the tick with ``joint_states``).
PIPELINE: tuple[Stage, ...] = (PLANT, INTERPOLATOR, ESTIMATOR, COMPENSATOR, SERVO, FORCE_REGULATOR)
STAGES: dict[str, Stage] = {s.name: s for s in PIPELINE}


@dataclass(frozen=True)
class Pipeline:
    """The stages of one run, in tick order, with the run's axes and the optional outputs it switches on."""

    stages: tuple[Stage, ...]
    axes: tuple[str, ...]
    outputs_on: frozenset[str] = frozenset()

    @property
    def names(self) -> tuple[str, ...]:
        """Stage names in tick order."""
        return tuple(s.name for s in self.stages)

    def has(self, name: str) -> bool:
        """True when stage ``name`` is part of the run."""
        return name in self.names

    def produced(self) -> tuple[str, ...]:
        """Relative names of every topic some stage of the run publishes (per-axis topics expanded)."""
        return tuple(n for s in self.stages for pattern in self.outputs_of(s)
                     for n in t.topic(pattern).names(self.axes))

    def outputs_of(self, stage: Stage) -> tuple[str, ...]:
        """The topic patterns ``stage`` publishes in this run (optional outputs only when switched on)."""
        return stage.outputs + tuple(p for p in stage.optional_outputs if p in self.outputs_on)

    def inputs_of(self, stage: Stage) -> tuple[str, ...]:
        """The topic patterns ``stage`` waits for each tick in this run (optional inputs only if produced)."""
        outputs = {pattern for s in self.stages for pattern in self.outputs_of(s)}
        return stage.inputs + tuple(p for p in stage.optional_inputs if p in outputs)

    def per_tick_topics(self) -> tuple[str, ...]:
        """Relative names of the topics that carry one message per tick in this run."""
        return tuple(n for n in self.produced() if t.type_of(n, self.axes) and _per_tick(n, self.axes))

    def recorded_topics(self) -> dict[str, str]:
        """Relative topic name -> type of everything a recorder of this run records."""
        names = (*self.produced(), t.DIAGNOSTICS.name)
        return {n: t.type_of(n, self.axes) for n in names}

    def node_inputs(self, stage: Stage) -> dict[str, tuple[str, ...]]:
        """Node name -> relative topic names it waits for each tick (a per-axis node reads its own axis)."""
        patterns = [t.topic(p) for p in self.inputs_of(stage)]
        if not stage.per_axis:
            return {stage.name: tuple(n for p in patterns for n in p.names(self.axes))}
        return {node: tuple(n for p in patterns for n in p.names([axis]))
                for axis, node in zip(self.axes, stage.node_names(self.axes))}

    def readers(self, topic_name: str) -> tuple[str, ...]:
        """Node names of the run that read ``topic_name`` (relative, per-axis expanded) every tick."""
        return tuple(node for stage in self.stages for node, names in self.node_inputs(stage).items()
                     if topic_name in names)


def _per_tick(name: str, axes: Sequence[str]) -> bool:
    for topic in t.TOPICS.values():
        if name in topic.names(axes):
            return topic.per_tick
    return False


def pipeline(axes: Sequence[str], optional: Collection[str] = (), outputs: Collection[str] = ()) -> Pipeline:
    """The pipeline of a run on ``axes`` with the ``optional`` stages and optional ``outputs`` asked for (by name)."""
    known = {s.name for s in PIPELINE if s.optional}
    unknown = sorted(set(optional) - known)
    if unknown:
        raise ConfigError(f"stage must be one of {sorted(known)}, got {unknown[0]!r}")
    known_outputs = {p for s in PIPELINE for p in s.optional_outputs}
    unknown = sorted(set(outputs) - known_outputs)
    if unknown:
        raise ConfigError(f"optional output must be one of {sorted(known_outputs)}, got {unknown[0]!r}")
    if not axes:
        raise ConfigError("a pipeline needs at least one axis")
    chosen = tuple(s for s in PIPELINE if not s.optional or s.name in optional)
    return Pipeline(chosen, tuple(axes), frozenset(outputs))
