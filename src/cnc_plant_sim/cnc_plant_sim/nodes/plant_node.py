"""Plant node: simulated feed drives. Owns /clock, publishes joint_states (and tool_position with machine
faults, cutting_force with a cutting process), applies commands (AxisCommand per axis, or JointState:
cnc_plant_sim.run.command_source). A commanding node leaving the graph mid-run stops the machine with a fault."""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import ParameterDescriptor
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from cnc_contour_control.axis.safety import EstopLatch
from cnc_contour_control.core.errors import CncError, ConfigError
from cnc_contour_control.core.lockstep import NS_PER_S, StampMatcher
from cnc_contour_control.core.params import flat_specs
from cnc_contour_control.core.topics import RUN_FINISHED, TICKS_KEY
from cnc_contour_control.nodes.common import (
    LOCKSTEP_QOS,
    ReaderGate,
    SuiteNode,
    describe,
    spin_node,
    stamp_to_ns,
    type_name_of,
    wall_time_s,
)
from cnc_contour_control.nodes.parameters import ConfigParameters, Section, declare_config, nested
from cnc_contour_control.nodes.safety_io import PartnerMonitor, SafetyInterface
from cnc_contour_control.nodes.spindle_parameter import watch_spindle_rpm
from cnc_contour_interfaces.msg import AxisCommand
from cnc_plant_sim.models.axis import AxisConfig
from cnc_plant_sim.models.friction import friction_config_class
from cnc_plant_sim.models.machine_faults import AxisFaults, FaultedPlant, MachineFaults, tool_positions_m
from cnc_plant_sim.models.periodic_load import set_spindle_rpm
from cnc_plant_sim.models.plant import MODEL_SECTIONS, PLANTS, PlantConfig, make_plant, other_section_error
from cnc_plant_sim.nodes.conversions import clock_msg, command_value, joint_command_values, joint_state_msg, wrench_msg
from cnc_plant_sim.process.cutting import CuttingConfig, cutting_plant
from cnc_plant_sim.process.turning import TurningConfig
from cnc_plant_sim.run.command_source import CommandSourceParams, command_interface
from cnc_plant_sim.run.run_clock import RunClock
from cnc_plant_sim.run.run_params import PlantRunParams
from cnc_plant_sim.run.watchdog import CommandWatchdog

#: Per-axis overrides of the model are the parameters ``axis_overrides.<axis>.<key>`` (keys of the model's
#: ``PLANTS[model].axis_config``, :class:`AxisConfig` for feed drives) and
#: ``axis_overrides.<axis>.friction_params.<key>`` (the keys of the axis's friction model).
OVERRIDES = "axis_overrides"
#: Machine faults are the parameters ``faults.*`` (:class:`MachineFaults` but its axes) and
#: ``faults.axes.<axis>.<key>`` (the keys of :class:`AxisFaults`), unset unless given.
FAULTS = "faults"
#: A cutting process is the parameters ``cutting.*`` (:class:`CuttingConfig`, schedules as two flat lists) and
#: ``cutting.turning.*`` (:class:`TurningConfig` but its ``depth_schedule``, which the two lists give).
CUTTING = "cutting"


def plant_parameters(node: SuiteNode) -> ConfigParameters[PlantConfig]:
    """PlantConfig's fields as parameters, the model's own section only (``variation.*``, ``mass_friction.*`` or
    ``velocity_loop.*``, as a servo's ``gains.*``), and each axis's overrides, unset unless given."""
    parameters = ConfigParameters(node, lambda mapping: PlantConfig.from_mapping(mapping))
    values = parameters.add(Section(PlantConfig, skip=(OVERRIDES, FAULTS, CUTTING, *MODEL_SECTIONS)))
    axes = values["axes"]
    axes = [a for a in axes if isinstance(a, str)] if isinstance(axes, list) else []
    entry = PLANTS.get(values["model"])  # an unknown model: declare() reports it with the config's error
    if entry is not None:
        _refuse_other_sections(node, values["model"])
        parameters.add(Section(entry.options, entry.section))
    axis_config = entry.axis_config if entry is not None else AxisConfig
    for axis in axes:
        parameters.add(Section(axis_config, f"{OVERRIDES}.{axis}", skip=("name", "friction_params"), unset=True))
    parameters.add(Section(MachineFaults, FAULTS, skip=("axes",)))
    for axis in axes:
        parameters.add(Section(AxisFaults, f"{FAULTS}.axes.{axis}", unset=True))
    parameters.add(Section(CuttingConfig, CUTTING, skip=("turning",)))
    parameters.add(Section(TurningConfig, f"{CUTTING}.turning", skip=("depth_schedule",)))
    for axis, friction in _frictions(parameters, axes).items():
        parameters.add(Section(friction_config_class(friction), f"{OVERRIDES}.{axis}.friction_params", unset=True,
                               read_only=True))
    return parameters


def _refuse_other_sections(node: SuiteNode, model: str) -> None:
    """A parameter of another model's section (``mass_friction.*`` for paper000) given to this plant is an error
    naming it and the model, as in a plant config: the node would not declare it, so it would do nothing."""
    for section, options in MODEL_SECTIONS.items():
        for name in (f"{section}.{spec.name}" for spec in flat_specs(options) if section != PLANTS[model].section):
            given = node.declare_parameter(name, None, ParameterDescriptor(dynamic_typing=True)).value
            node.undeclare_parameter(name)
            if given is not None:
                raise ConfigError(f"{name}: {other_section_error(model, section)}")


def _frictions(parameters: ConfigParameters[PlantConfig], axes: list[str]) -> dict[str, str]:
    """Each axis's friction model, the overridden one or the model's: its params are the axis's friction_params."""
    given = {axis: parameters.values.get(f"{OVERRIDES}.{axis}.friction") for axis in axes}
    model_values = {k: v for k, v in parameters.values.items() if not k.endswith(".friction")}
    try:
        nominal = [a.friction for a in parameters.build(nested(model_values)).nominal_axes()]
    except CncError:
        nominal = []  # no feed drives, or a bad value that declare() reports with the config's error
    frictions = dict(zip(axes, nominal))
    frictions.update({axis: name for axis, name in given.items() if isinstance(name, str)})
    return {axis: name for axis, name in frictions.items() if isinstance(name, str)}


class PlantNode(SuiteNode):
    """Lockstep: integrates once every axis's command for the tick is in. Real time: on a wall timer."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("plant", **kwargs)

    def configure(self) -> None:
        """Lifecycle configure (nodes/lifecycle.py): the parameters validated, the model built, the topics."""
        run = declare_config(self, PlantRunParams)
        self.plant = make_plant(plant_parameters(self).declare())
        self.axes = self.plant.axis_names
        self.plant.reset(run.positions_m(len(self.axes)))
        self.clock = RunClock(run.sample_time_s, run.duration_s)
        self.mode = run.mode
        self.summary_file = run.summary_file
        self.matcher = StampMatcher(self.axes, run.command_timeout_s, run.startup_timeout_s,
                                    max_ahead_ns=0)  # only the tick it published
        self.commands = [0.0] * len(self.axes)
        self.received = [False] * len(self.axes)
        self.watchdog = CommandWatchdog(run, len(self.axes), self.axes, run.sample_time_s)  # real time only
        self.latch = EstopLatch()  # estop, ~/enable, ~/reset: zero commands while latched or disabled
        self.safety = SafetyInterface(self, self.latch, lambda: self.clock.stamp_ns)
        self.started = False
        self.loop_closed = False  # real time: the wall clock runs once tick 0's commands are in
        self.joint_pub = self.create_publisher(JointState, "joint_states", LOCKSTEP_QOS)
        self.joint_gate = self.reader_gate(self.joint_pub, JointState, "expected_subscribers", 1)
        self.tool_pub, self.tool_gate = self._tool_position_publisher()
        self.cutting = cutting_plant(self.plant)
        self.spindle_override = watch_spindle_rpm(  # the periodic disturbance's speed from now on
            self, lambda rpm: set_spindle_rpm(self.plant, rpm, self.clock.sample_time_s), "plant")
        self.force_pub, self.force_gate = self._cutting_force_publisher()
        self.clock_pub = self.create_publisher(Clock, "/clock", LOCKSTEP_QOS)
        self.command_topics = self._subscribe_commands(declare_config(self, CommandSourceParams))
        # a commanding node that leaves while a tick waits faults the run; while paused (deactivated, the next
        # tick held) none waits: a servo may be cleaned up and configured anew (nodes/lifecycle.py)
        self.partners = PartnerMonitor(self, self.command_topics, lambda: self.started and not self._tick_held,
                                       self._partner_lost, lambda: self.clock.stamp_ns)
        self.create_timer(0.02, self.guarded(self._wait_for_graph))
        self.create_timer(0.1, self.guarded(self._watchdog))
        self.create_timer(1.0, self._write_progress)
        self._tick_held = False  # lockstep, deactivated: the next tick waits for activate

    def activate(self) -> None:
        """Lifecycle activate: the run starts (once the graph is ready) or resumes; real time: drives enabled."""
        if self.mode == "realtime" and self.started:
            answer = self.latch.enable(True)
            if not answer.accepted:
                raise CncError(answer.message)
        if self._tick_held:
            self._tick_held = False
            self._publish_tick()

    def deactivate(self) -> None:
        """Lifecycle deactivate: lockstep, the run pauses after this tick (nothing moves, time stands);
        real time, the drives are switched off (zero commands) and the axes come to rest."""
        if self.mode == "realtime":
            self.latch.enable(False)

    def _tool_position_publisher(self) -> tuple[Any, ReaderGate | None]:
        """``tool_position`` and its gate (``tool_position_subscribers`` readers) when the plant has faults."""
        count = self.declare("tool_position_subscribers", 0, describe(
            "readers of tool_position (recorders) to wait for before publishing", 0, 1000, True, True))
        if not isinstance(self.plant, FaultedPlant):
            return None, None
        publisher = self.create_publisher(JointState, "tool_position", LOCKSTEP_QOS)
        return publisher, ReaderGate(self, publisher, type_name_of(JointState), (), count)

    def _cutting_force_publisher(self) -> tuple[Any, ReaderGate | None]:
        """``cutting_force`` and its gate (``cutting_force_subscribers`` readers) when the plant cuts."""
        count = self.declare("cutting_force_subscribers", 0, describe(
            "readers of cutting_force (force regulator, recorders) to wait for before publishing", 0, 1000, True,
            True))
        if self.cutting is None:
            return None, None
        publisher = self.create_publisher(WrenchStamped, "cutting_force", LOCKSTEP_QOS)
        return publisher, ReaderGate(self, publisher, type_name_of(WrenchStamped), (), count)

    def _subscribe_commands(self, source: CommandSourceParams) -> list[str]:
        """Subscribe the command source; the resolved topics the commands come on."""
        if source.command_source == "axis_command":
            for axis in self.axes:
                self.subscribe_checked(AxisCommand, f"servo/{axis}/command", self._command_callback(axis))
            return [self.resolve_topic_name(f"servo/{axis}/command") for axis in self.axes]
        field = command_interface(self.plant.command_unit)

        def on_joint_command(msg: JointState) -> None:
            stamp_ns = stamp_to_ns(msg.header.stamp)
            for axis, value in joint_command_values(msg, self.axes, field).items():
                self._take_command(axis, stamp_ns, value)

        self.subscribe_checked(JointState, source.joint_command_topic, on_joint_command)
        return [self.resolve_topic_name(source.joint_command_topic)]

    def _wait_for_graph(self) -> None:
        if self.started or not self.armed:
            return
        ready = all(self.count_publishers(topic) >= 1 for topic in self.command_topics)
        gates = [g for g in (self.joint_gate, self.tool_gate, self.force_gate) if g is not None]
        stalled = next((m for m in (g.overdue(self.matcher.startup_timeout_s) for g in gates) if m), None)
        if stalled:
            self.fault(f"plant: {stalled}")
        elif ready and all(g.ready() for g in gates):
            self.started = True
            self.partners.check()  # who commands: known from the start, however short the run
            self.clock.started_wall_s = wall_time_s()
            self.get_logger().info(f"graph ready, running {self.mode} for {self.clock.duration_s} s")
            self._publish_tick()

    def _close_loop(self, commands: list[float]) -> None:
        """Real time: tick 0's commands are in from every axis, so the wall clock starts now.

        Until the controller answers once, the loop is open: a servo whose
        reader matched the plant's writer late (discovery on a loaded host)
        would otherwise see its first commands counted late and fault the run
        before it ever closed the loop. The wait is the startup timeout, as in
        lockstep.
        """
        self.loop_closed = True
        self.commands = list(commands)
        self.received = [True] * len(self.axes)
        self.clock.started_wall_s = self.last_wall_s = wall_time_s()
        self.create_timer(self.clock.sample_time_s, self.guarded(self._realtime_tick))

    def _publish_tick(self) -> None:
        stamp_ns = self.clock.stamp_ns
        # joint_states first: it starts the next stages; /clock is off the critical path.
        positions_m, velocities_m_s = self.plant.state()
        self.joint_pub.publish(joint_state_msg(self.axes, positions_m, velocities_m_s, stamp_ns))
        if self.tool_pub is not None:
            self.tool_pub.publish(joint_state_msg(self.axes, tool_positions_m(self.plant), (), stamp_ns))
        if self.force_pub is not None and self.cutting is not None:
            self.force_pub.publish(wrench_msg(self.cutting.cutting_force_n(), stamp_ns))
        self.clock_pub.publish(clock_msg(stamp_ns))
        if self.mode == "lockstep" or not self.loop_closed:
            self.matcher.expect(stamp_ns, wall_time_s())

    def _command_callback(self, axis: str) -> Any:
        def on_command(msg: AxisCommand) -> None:
            self._take_command(axis, stamp_to_ns(msg.header.stamp), command_value(msg, axis))

        return on_command

    def _take_command(self, axis: str, stamp_ns: int, value: float) -> None:
        """One axis's command for tick ``stamp_ns``: held for the real-time tick, or matched in lockstep."""
        if self.mode == "realtime" and self.loop_closed:
            if stamp_ns == self.clock.stamp_ns:
                index = self.axes.index(axis)
                self.commands[index] = value
                self.received[index] = True
            return
        items = self.matcher.add(axis, stamp_ns, value, wall_time_s())
        if items is None:
            return
        commands = [items[a] for a in self.axes]
        if self.mode == "realtime":
            self._close_loop(commands)
        else:
            self._lockstep_step(commands)

    def _lockstep_step(self, commands: list[float]) -> None:
        self.plant.step(self.latch.gate(commands), self.clock.sample_time_s)
        self.safety.account(self.clock.stamp_ns, wall_time_s())
        self.clock.advance()
        if self.clock.done:
            self._finish()
        elif not self.armed:
            self._tick_held = True
        else:
            self._publish_tick()

    def _realtime_tick(self) -> None:
        now_s = wall_time_s()
        period_ns = round((now_s - self.last_wall_s) * NS_PER_S)
        self.last_wall_s = now_s
        received, self.received = self.received, [False] * len(self.axes)
        commands = self.watchdog.tick(self.clock.stamp_ns, received, self.commands)
        self.clock.late_commands = self.watchdog.late_commands
        self.plant.step(self.latch.gate(commands), period_ns / NS_PER_S)
        n_axes = len(self.axes)
        self.safety.account(self.clock.stamp_ns, now_s, {"late_commands": (n_axes - sum(received), n_axes)})
        self.watchdog.check()  # a late share past max_late_share faults the run
        self.clock.advance(period_ns)
        if self.clock.done:
            self._finish()
        else:
            self._publish_tick()

    def run_stamp_ns(self) -> int:
        """The run's time for a status: the stamp of the plant's tick (0 before its clock exists)."""
        clock = getattr(self, "clock", None)  # built in configure: a refused configure reports before it
        return 0 if clock is None else int(clock.stamp_ns)

    def fault(self, message: str) -> None:
        """Fault as every node does, and keep the run's summary."""
        super().fault(message)
        self._write_summary()

    def _watchdog(self) -> None:
        overdue = self.matcher.overdue(wall_time_s())
        if overdue is not None:
            stamp_ns, missing = overdue
            topics = ", ".join(sorted({self._command_topic(a) for a in missing}))
            self._stop(f"plant: no {topics} for tick t={stamp_ns / NS_PER_S:.6f} s within "
                       f"{self.matcher.current_timeout_s} s")

    def _command_topic(self, axis: str) -> str:
        """The resolved topic ``axis``'s command comes on, and who last published it."""
        topic = self.command_topics[self.axes.index(axis)] if len(self.command_topics) > 1 else self.command_topics[0]
        return topic + self.partners.last_publishers(topic)

    def _partner_lost(self, message: str) -> None:
        """A commanding node left the graph mid-run: stop the machine and fault naming it."""
        self._stop(f"plant: {message}; machine stopped")

    def _stop(self, message: str) -> None:
        """Latch (zero commands, as the e-stop does) and fault: the machine stops, the run ends faulted."""
        if self.latch.trip(message):
            self.safety.latched(message)
        self.fault(message)

    def _finish(self) -> None:
        self.clock.finished_wall_s = wall_time_s()
        self._write_summary()
        self.get_logger().info(f"run finished: {self.clock.tick} ticks")
        self.finished = True
        self.report(DiagnosticStatus.OK, RUN_FINISHED, {TICKS_KEY: str(self.clock.tick)}, stamp_ns=self.clock.stamp_ns)

    def _write_progress(self) -> None:
        if self.started and not self.finished:
            self._write_summary("running")

    def _write_summary(self, status: str | None = None, reason: str = "") -> None:
        """Write the run's summary: ``running`` while it runs, then how it ended (finished, faulted, interrupted)."""
        if status is None:
            status = "faulted" if self.fault_message else "finished"
        if status != "running":
            self.clock.finished_wall_s = self.clock.finished_wall_s or wall_time_s()
        summary = self.clock.summary([self.fault_message] if self.fault_message else [], wall_time_s())
        summary.update(status=status, mode=self.mode, sample_time_s=self.clock.sample_time_s,
                       duration_s=self.clock.duration_s)
        if reason:
            summary["reason"] = reason
        summary["plant"] = self.plant.describe()
        summary["held_commands"] = self.watchdog.held_commands
        summary["estop_latches"] = self.latch.latch_count
        if self.summary_file:
            _replace_file(Path(self.summary_file), json.dumps(summary, indent=2))

    def destroy_node(self) -> None:
        """Leave a summary that says how the run ended, also when stopped from outside (SIGINT, SIGTERM)."""
        if not self.finished:
            self._write_summary("interrupted", "the plant was stopped before the run ended (signal or shutdown)")
        super().destroy_node()


def _replace_file(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically: a reader sees the old or the new file, never half of one."""
    partial = path.with_name(f".{path.name}.partial")
    partial.write_text(text)
    os.replace(partial, path)


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_plant_sim plant``."""
    raise SystemExit(spin_node(PlantNode, args))
