"""Servo node: one axis's position loop. Joint state + reference (+ compensation) -> command.

The reference is the Reference topic's, or a trajectory_msgs/JointTrajectory's sampled at each tick
(``reference_source``, cnc_contour_control.motion.trajectory_reference). The law is frozen while the e-stop latch
blocks commands (cnc_contour_control.axis.servo_hold); an input's publisher leaving mid-tick is a fault naming it.
A following-error trip faults (``ferror_action: fault``) or latches and e-stops the machine (``latch``).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from cnc_contour_control.axis.safety import EstopLatch, FerrorActionParams
from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.axis.servo_hold import HeldServo, HoldParams
from cnc_contour_control.axis.spindle_override import law_receiver
from cnc_contour_control.core.errors import CncError
from cnc_contour_control.core.lockstep import NS_PER_S, StampMatcher, seconds_to_ns, stamp_horizon_ns
from cnc_contour_control.graph.stage_params import SERVO_GAINS, SERVO_NODE_SKIPS, ServoRunParams
from cnc_contour_control.laws import law_config_class
from cnc_contour_control.motion.trajectory_reference import ReferenceSourceParams, TrajectoryFollower
from cnc_contour_control.nodes.common import (
    SuiteNode,
    spin_node,
    wall_time_s,
)
from cnc_contour_control.nodes.conversions import (
    command_to_msg,
    compensation_for,
    joint_position,
    joint_velocity,
    reference_axis,
)
from cnc_contour_control.nodes.parameters import ConfigParameters, Section, declare_config
from cnc_contour_control.nodes.safety_io import PartnerMonitor, SafetyInterface
from cnc_contour_control.nodes.spindle_parameter import watch_spindle_rpm
from cnc_contour_control.nodes.trajectory_io import subscribe_trajectory
from cnc_contour_interfaces.msg import AxisCommand, Compensation, Reference


def servo_parameters(node: SuiteNode, axis: str) -> ConfigParameters[ServoConfig]:
    """ServoConfig's fields as parameters (the axis is the run's) and the chosen law's gains as ``gains.*``."""

    def build(mapping: dict[str, Any]) -> ServoConfig:
        values = {key: value for key, value in mapping.items() if key != SERVO_GAINS}
        return ServoConfig.from_mapping({**values, "axis_name": axis, "law_params": mapping.get(SERVO_GAINS, {})},
                                        context=f"servo[{axis}]")

    parameters = ConfigParameters(node, build)
    law = parameters.add(Section(ServoConfig, skip=SERVO_NODE_SKIPS))["law"]
    parameters.add(Section(law_config_class(law), SERVO_GAINS))
    return parameters


class ServoNode(SuiteNode):
    """Closes one axis's loop in lockstep: a command for every matched tick."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("servo", **kwargs)

    def configure(self) -> None:
        """Lifecycle configure (nodes/lifecycle.py): the parameters validated, the law built, the topics."""
        run = declare_config(self, ServoRunParams)
        self.axis = run.axis
        self.sample_time_ns = seconds_to_ns(run.sample_time_s)
        self.parameters = servo_parameters(self, self.axis)
        self.controller = ServoController(self.parameters.declare())
        self.spindle_override = watch_spindle_rpm(self, law_receiver(self.controller.law), f"servo {self.axis}")
        self.parameters.watch(self._retune)  # gains change, the law's state stays
        source = declare_config(self, ReferenceSourceParams)
        self.trajectory = (TrajectoryFollower(self.axis, travel_mm=source.travel)
                           if source.reference_source == "joint_trajectory" else None)
        inputs = (["joint_states"] + (["reference"] if self.trajectory is None else [])
                  + (["compensation"] if run.use_compensation else []))
        self.matcher = StampMatcher(inputs, run.input_timeout_s, run.startup_timeout_s,
                                    stamp_horizon_ns(self.sample_time_ns))
        self.last_stamp_ns: int | None = None
        self.command_pub = self.gated_publisher(AxisCommand, f"servo/{self.axis}/command", 1)
        self._subscribe(JointState, "joint_states")
        if self.trajectory is None:
            self._subscribe(Reference, "reference")
        else:
            subscribe_trajectory(self, JointTrajectory, source.trajectory_topic, self.trajectory)
        if run.use_compensation:
            self._subscribe(Compensation, "compensation")
        self.watch_inputs(self.matcher, f"servo {self.axis}")
        self.latch = EstopLatch()  # estop, ~/enable, ~/reset: the law is frozen while commands are blocked
        action = declare_config(self, FerrorActionParams).ferror_action
        self.held = HeldServo(self.controller, self.latch, declare_config(self, HoldParams), action)
        self.diagnostics = SafetyInterface(self, self.latch, self._stamp_ns,  # every second: saturation, peak error
                                           trips_machine=action == "latch")
        self.partners = PartnerMonitor(self, inputs[1:], lambda: self.matcher.pending_count > 0,
                                       lambda lost: self.fault(f"servo {self.axis}: {lost}"), self._stamp_ns)

    def activate(self) -> None:
        """Lifecycle activate: the axis enabled (refused while the e-stop is latched, naming the cause)."""
        answer = self.latch.enable(True)
        if not answer.accepted:
            raise CncError(answer.message)

    def deactivate(self) -> None:
        """Lifecycle deactivate: the axis disabled (zero commands, the law frozen), as ``~/enable false``."""
        self.latch.enable(False)

    def _stamp_ns(self) -> int:
        """The last tick's stamp (0 before the first)."""
        return self.last_stamp_ns or 0

    def _retune(self, config: ServoConfig) -> None:
        """New gains; a live ``spindle_rpm`` stays in force over the gains' design speed."""
        self.controller.retune(config)
        refused = self.spindle_override.reapply()
        if refused is not None:
            self.report(DiagnosticStatus.WARN, f"servo {self.axis}: {refused}")

    def _subscribe(self, msg_type: type, topic: str) -> None:
        decode = _DECODE[topic]
        self.subscribe_matched(self.matcher, msg_type, topic, lambda msg: decode(msg, self.axis), self._step)

    def _step(self, items: dict[str, Any]) -> None:
        stamp_ns = self.matcher.last_released_ns
        assert stamp_ns is not None  # a tick was just released
        if self.last_stamp_ns is None:
            self.partners.check()  # who sends the inputs: known from the first tick on
        dt_ns = self.sample_time_ns if self.last_stamp_ns is None else stamp_ns - self.last_stamp_ns
        position_m, velocity_m_s = items["joint_states"]
        ref = items["reference"] if self.trajectory is None else self.trajectory.sample(stamp_ns, position_m)
        correction = items.get("compensation", 0.0)
        refused = self.controller.follow_spindle(stamp_ns)  # the commanded spindle speed, as the engine at this tick
        if refused is not None:
            self.report(DiagnosticStatus.WARN, f"servo {self.axis}: {refused}",
                        # a refusal comes only from a spindle follower
                        {"stamp_ns": str(stamp_ns),
                         "spindle_rpm": str(self.controller.spindle.commanded_rpm)})  # type: ignore[union-attr]  # see above
        # the following-error trip is checked in there, while enabled (LinuxCNC), as the engine checks it
        output = self.held.step(stamp_ns, dt_ns / NS_PER_S, ref[0], ref[1], ref[2], position_m, velocity_m_s,
                                correction)
        self.last_stamp_ns = stamp_ns
        config = self.controller.config
        trip = self.held.take_trip()  # ferror_action latch: the command is already 0
        if trip is not None:
            self.diagnostics.trip_machine(trip)
        self.diagnostics.account(stamp_ns, wall_time_s(), {"saturated": (int(output.saturated), 1)},
                                 {"peak_following_error_m": output.error_m})
        self.command_pub.publish(command_to_msg(output, self.axis, config.law, config.command_unit, stamp_ns))


#: Each input decoded and checked on arrival: this axis's values (a fault names the field); the tick uses them.
_DECODE: dict[str, Callable[[Any, str], Any]] = {
    "joint_states": lambda msg, axis: (joint_position(msg, axis), joint_velocity(msg, axis)),
    "reference": reference_axis,
    "compensation": compensation_for,
}


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_contour_control servo --ros-args -p axis:=x``."""
    raise SystemExit(spin_node(ServoNode, args))
