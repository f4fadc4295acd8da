"""Plant node: simulated feed drives. Owns /clock, publishes joint_states, applies commands."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml
from cnc_contour_interfaces.msg import AxisCommand
from diagnostic_msgs.msg import DiagnosticStatus
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from cnc_contour_control.errors import ConfigError
from cnc_contour_control.lockstep import NS_PER_S, StampMatcher
from cnc_contour_control.nodes.common import (
    LOCKSTEP_QOS,
    SuiteNode,
    describe,
    spin_node,
    stamp_to_ns,
    wall_time_s,
)
from cnc_plant_sim.nodes.conversions import clock_msg, command_value, joint_state_msg
from cnc_plant_sim.plant import PlantConfig, make_plant
from cnc_plant_sim.run_clock import RunClock

MODES = ("lockstep", "realtime")
#: Status message announcing the end of a run (its value "ticks" counts the ticks published).
RUN_FINISHED = "run finished"


class PlantNode(SuiteNode):
    """Lockstep: integrates once every axis's command for the tick is in. Real time: on a wall timer."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("plant", **kwargs)
        self.plant = make_plant(self._plant_config())
        self.axes = self.plant.axis_names
        initial = self.declare("initial_position_m", [0.0], describe("initial axis positions, m", read_only=True))
        self.plant.reset(list(initial) * len(self.axes) if len(initial) == 1 else list(initial))
        self.clock = RunClock(
            self.declare("sample_time_s", 0.01, describe("sample time T, s", 1e-5, 1.0, True)),
            self.declare("duration_s", 10.0, describe("simulated duration of the run, s", 1e-3, 1e6, True)),
        )
        self.mode = self.declare("mode", "lockstep", describe(f"time mode: {list(MODES)}", read_only=True))
        if self.mode not in MODES:
            raise ConfigError(f"mode must be one of {list(MODES)}, got {self.mode!r}")
        self.expected_subscribers = self.declare("expected_subscribers", 1, describe("joint_states subscribers to wait for before tick 0", 0, 1000, True, True))
        self.summary_file = self.declare("summary_file", "", describe("write the run summary here as JSON", read_only=True))
        timeout_s = self.declare("command_timeout_s", 5.0, describe("wall time to wait for a tick's commands, s", 0.01, 600.0, True))
        startup_s = self.declare("startup_timeout_s", 90.0, describe(
            "wall time the first tick may wait (graph discovery), s", 0.01, 3600.0, True))
        self.matcher = StampMatcher(self.axes, timeout_s, startup_s)
        self.commands = [0.0] * len(self.axes)
        self.received = [False] * len(self.axes)
        self.started = False
        self.joint_pub = self.create_publisher(JointState, "joint_states", LOCKSTEP_QOS)
        self.clock_pub = self.create_publisher(Clock, "/clock", LOCKSTEP_QOS)
        for axis in self.axes:
            self.create_subscription(AxisCommand, f"servo/{axis}/command", self.guarded(self._command_callback(axis)), LOCKSTEP_QOS)
        self.create_timer(0.02, self.guarded(self._wait_for_graph))
        self.create_timer(0.1, self.guarded(self._watchdog))
        self.create_timer(1.0, self._write_progress)

    def _plant_config(self) -> PlantConfig:
        overrides = yaml.safe_load(self.declare("axis_overrides", "{}", describe("per-axis model overrides as a YAML mapping", read_only=True))) or {}
        return PlantConfig.from_mapping({
            "model": self.declare("model", "paper000", describe("plant model (registry name)", read_only=True)),
            "axes": tuple(self.declare("axes", ["x", "y"], describe("axis names, in order", read_only=True))),
            "seed": self.declare("seed", 0, describe("seed of the parameter variations", 0, 2**31 - 1, True, True)),
            "substeps": self.declare("substeps", 1, describe("integration sub-steps per sample", 1, 1000, True, True)),
            "variation": {
                "gain_pct": self.declare("gain_variation_pct", 5.0, describe("K variation, +-%", 0.0, 50.0, True)),
                "time_constant_pct": self.declare("time_constant_variation_pct", 5.0, describe("tau variation, +-%", 0.0, 50.0, True)),
                "friction_pct": self.declare("friction_variation_pct", 8.0, describe("friction variation, +-%", 0.0, 50.0, True)),
            },
            "axis_overrides": overrides,
        })

    def _wait_for_graph(self) -> None:
        if self.started:
            return
        ready = all(self.count_publishers(self.resolve_topic_name(f"servo/{a}/command")) >= 1 for a in self.axes)
        if ready and self.joint_pub.get_subscription_count() >= self.expected_subscribers:
            self.started = True
            self.clock.started_wall_s = wall_time_s()
            self.get_logger().info(f"graph ready, running {self.mode} for {self.clock.duration_s} s")
            if self.mode == "realtime":
                self.create_timer(self.clock.sample_time_s, self.guarded(self._realtime_tick))
                self.last_wall_s = wall_time_s()
            self._publish_tick()

    def _publish_tick(self) -> None:
        stamp_ns = self.clock.stamp_ns
        # joint_states first: it starts the next stages; /clock is off the critical path.
        self.joint_pub.publish(joint_state_msg(self.axes, self.plant.positions_m(), self.plant.velocities_m_s(), stamp_ns))
        self.clock_pub.publish(clock_msg(stamp_ns))
        if self.mode == "lockstep":
            self.matcher.expect(stamp_ns, wall_time_s())

    def _command_callback(self, axis: str) -> Any:
        index = self.axes.index(axis)

        def on_command(msg: AxisCommand) -> None:
            value = command_value(msg, axis)
            stamp_ns = stamp_to_ns(msg.header.stamp)
            if self.mode == "realtime":
                if stamp_ns == self.clock.stamp_ns:
                    self.commands[index] = value
                    self.received[index] = True
                return
            items = self.matcher.add(axis, stamp_ns, value, wall_time_s())
            if items is not None:
                self._lockstep_step([items[a] for a in self.axes])

        return on_command

    def _lockstep_step(self, commands: list[float]) -> None:
        self.plant.step(commands, self.clock.sample_time_s)
        self.clock.advance()
        if self.clock.done:
            self._finish()
        else:
            self._publish_tick()

    def _realtime_tick(self) -> None:
        now_s = wall_time_s()
        period_ns = round((now_s - self.last_wall_s) * NS_PER_S)
        self.last_wall_s = now_s
        self.clock.late_commands += self.received.count(False)
        self.received = [False] * len(self.axes)
        self.plant.step(self.commands, period_ns / NS_PER_S)
        self.clock.advance(period_ns)
        if self.clock.done:
            self._finish()
        else:
            self._publish_tick()

    def fault(self, message: str) -> None:
        """Fault as every node does, and keep the run's summary."""
        super().fault(message)
        self._write_summary()

    def _watchdog(self) -> None:
        overdue = self.matcher.overdue(wall_time_s())
        if overdue is not None:
            stamp_ns, missing = overdue
            topics = ", ".join(self.resolve_topic_name(f"servo/{a}/command") for a in missing)
            self.fault(f"plant: no {topics} for tick t={stamp_ns / NS_PER_S:.6f} s within {self.matcher.current_timeout_s} s")

    def _finish(self) -> None:
        self.clock.finished_wall_s = wall_time_s()
        self._write_summary()
        self.get_logger().info(f"run finished: {self.clock.tick} ticks")
        self.finished = True
        self.report(DiagnosticStatus.OK, RUN_FINISHED, {"ticks": str(self.clock.tick)})

    def _write_progress(self) -> None:
        if self.started and not self.finished:
            self._write_summary("running")

    def _write_summary(self, status: str | None = None) -> None:
        if status is None:
            status = "faulted" if self.fault_message else "finished"
            self.clock.finished_wall_s = self.clock.finished_wall_s or wall_time_s()
        summary = self.clock.summary([self.fault_message] if self.fault_message else [], wall_time_s())
        summary["status"] = status
        summary["plant"] = self.plant.describe()
        if self.summary_file:
            Path(self.summary_file).write_text(json.dumps(summary, indent=2))


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_plant_sim plant``."""
    raise SystemExit(spin_node(PlantNode, args))
