"""Servo node: one axis's position loop. Joint state + reference (+ compensation) -> command."""
from __future__ import annotations

from typing import Any

import yaml
from cnc_contour_interfaces.msg import AxisCommand, Compensation, Reference
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from cnc_contour_control.errors import CncError, ConfigError
from cnc_contour_control.lockstep import NS_PER_S, StampMatcher, seconds_to_ns
from cnc_contour_control.nodes.common import (
    LOCKSTEP_QOS,
    SuiteNode,
    describe,
    spin_node,
    stamp_to_ns,
    wall_time_s,
)
from cnc_contour_control.nodes.conversions import (
    command_to_msg,
    compensation_for,
    joint_position,
    reference_axis,
)
from cnc_contour_control.servo import ServoConfig, ServoController

#: Parameters that build the ServoConfig (all but ``law_params`` are plain values).
_CONFIG_PARAMETERS = ("law", "law_params", "counts_per_m", "ff1", "ff2", "output_limit", "quantum", "command_unit")


class ServoNode(SuiteNode):
    """Closes one axis's loop in lockstep: a command for every matched tick."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("servo", **kwargs)
        self.axis = self.declare("axis", "x", describe("axis this servo drives", read_only=True))
        self.sample_time_ns = seconds_to_ns(
            self.declare("sample_time_s", 0.01, describe("nominal sample time (first tick), s", 1e-5, 1.0, True))
        )
        use_compensation = self.declare("use_compensation", False, describe("wait for and add /compensation", read_only=True))
        timeout_s = self.declare("input_timeout_s", 5.0, describe("wall time a tick may wait for its inputs, s", 0.01, 600.0, True))
        self._declare_config()
        self.controller = ServoController(self._config_from({}))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        inputs = ["joint_states", "reference"] + (["compensation"] if use_compensation else [])
        startup_s = self.declare("startup_timeout_s", 30.0, describe(
            "wall time the first tick may wait (graph discovery), s", 0.01, 3600.0, True))
        self.matcher = StampMatcher(inputs, timeout_s, startup_s)
        self.last_stamp_ns: int | None = None
        self.command_pub = self.gated_publisher(AxisCommand, f"servo/{self.axis}/command", 1)
        self._subscribe(JointState, "joint_states")
        self._subscribe(Reference, "reference")
        if use_compensation:
            self._subscribe(Compensation, "compensation")
        self.create_timer(0.1, self.guarded(self._watchdog))

    def _declare_config(self) -> None:
        self.declare("law", "pid", describe("feedback law (registry name: pid, p, fuzzy, ...)"))
        self.declare("law_params", "{}", describe("law parameters as a YAML mapping, e.g. '{kp: 2.4, ki: 0.1, kd: 6.7}'"))
        self.declare("counts_per_m", 1.0e5, describe("law length units per metre (1e5 = BLU of 10 um)", 1e-3, 1e12, True))
        self.declare("ff1", 0.0, describe("velocity feedforward, command per law unit/s", -1e6, 1e6))
        self.declare("ff2", 0.0, describe("acceleration feedforward, command per law unit/s^2", -1e6, 1e6))
        self.declare("output_limit", 127.0, describe("symmetric command saturation, drive units", 1e-9, 1e12, True))
        self.declare("quantum", 1.0, describe("command quantisation step, drive units (0 = none)", 0.0, 1e6, True))
        self.declare("command_unit", "dac", describe("unit of the command (dac, V, N)", read_only=True))

    def _config_from(self, changes: dict[str, Any]) -> ServoConfig:
        values = {name: self.get_parameter(name).value for name in _CONFIG_PARAMETERS}
        values.update(changes)
        try:
            law_params = yaml.safe_load(values["law_params"]) or {}
        except yaml.YAMLError as err:
            raise ConfigError(f"law_params is not a YAML mapping: {err}") from err
        if not isinstance(law_params, dict):
            raise ConfigError(f"law_params must be a YAML mapping, got {values['law_params']!r}")
        values["law_params"] = law_params
        return ServoConfig.from_mapping({"axis_name": self.axis, **values}, context=f"servo[{self.axis}]")

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        changes = {p.name: p.value for p in parameters if p.name in _CONFIG_PARAMETERS}
        if not changes:
            return SetParametersResult(successful=True)
        try:
            config = self._config_from(changes)
        except CncError as err:
            return SetParametersResult(successful=False, reason=str(err))
        self.controller = ServoController(config)
        return SetParametersResult(successful=True)

    def _subscribe(self, msg_type: type, topic: str) -> None:
        def on_message(msg: Any) -> None:
            items = self.matcher.add(topic, stamp_to_ns(msg.header.stamp), msg, wall_time_s())
            if items is not None:
                self._step(items)

        self.create_subscription(msg_type, topic, self.guarded(on_message), LOCKSTEP_QOS)

    def _step(self, items: dict[str, Any]) -> None:
        stamp_ns = stamp_to_ns(items["reference"].header.stamp)
        dt_ns = self.sample_time_ns if self.last_stamp_ns is None else stamp_ns - self.last_stamp_ns
        position_m = joint_position(items["joint_states"], self.axis)
        ref = reference_axis(items["reference"], self.axis)
        correction = compensation_for(items["compensation"], self.axis) if "compensation" in items else 0.0
        output = self.controller.step(dt_ns / NS_PER_S, ref[0], ref[1], ref[2], position_m, correction)
        self.last_stamp_ns = stamp_ns
        config = self.controller.config
        self.command_pub.publish(command_to_msg(output, self.axis, config.law, config.command_unit, stamp_ns))

    def _watchdog(self) -> None:
        overdue = self.matcher.overdue(wall_time_s())
        if overdue is not None:
            stamp_ns, missing = overdue
            topics = ", ".join(self.resolve_topic_name(name) for name in missing)
            self.fault(
                f"servo {self.axis}: no {topics} for tick t={stamp_ns / NS_PER_S:.6f} s "
                f"within {self.matcher.current_timeout_s} s"
            )


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_contour_control servo --ros-args -p axis:=x``."""
    raise SystemExit(spin_node(ServoNode, args))
