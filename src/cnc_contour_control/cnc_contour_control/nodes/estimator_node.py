"""Estimator node: joint state + reference -> ``contour_error`` every tick (paper 001's model or the path's)."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from cnc_contour_interfaces.msg import ContourError, Reference
from sensor_msgs.msg import JointState

from cnc_contour_control.cross_axis import EstimatorSettings
from cnc_contour_control.estimators import estimator_config_class
from cnc_contour_control.lockstep import NS_PER_S, StampMatcher, seconds_to_ns, stamp_horizon_ns
from cnc_contour_control.nodes.common import SuiteNode, spin_node, stamp_to_ns, wall_time_s
from cnc_contour_control.nodes.conversions import estimate_to_msg, joint_positions, reference_positions
from cnc_contour_control.nodes.method_params import method_parameters
from cnc_contour_control.nodes.parameters import declare_config
from cnc_contour_control.program_file import read_program_file
from cnc_contour_control.stage_params import EstimatorRunParams


class EstimatorNode(SuiteNode):
    """Publishes ``contour_error`` for every tick whose joint state and reference it holds.

    Parameters: :class:`~cnc_contour_control.stage_params.EstimatorRunParams`,
    ``method`` and the method's config as ``params.*``
    (:class:`~cnc_contour_control.cross_axis.EstimatorSettings`).
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("estimator", **kwargs)
        run = declare_config(self, EstimatorRunParams)
        self.axes = run.axes
        self.settings: EstimatorSettings = method_parameters(self, EstimatorSettings, estimator_config_class).declare()
        self.estimator = self.settings.make(read_program_file(run.program_file, self.axes))
        self.matcher = StampMatcher(("joint_states", "reference"), run.input_timeout_s, run.startup_timeout_s,
                                    stamp_horizon_ns(seconds_to_ns(run.sample_time_s)))
        self.publisher = self.gated_publisher(ContourError, "contour_error", 1)
        self._subscribe(JointState, "joint_states")
        self._subscribe(Reference, "reference")
        self.create_timer(0.1, self.guarded(self._watchdog))

    def _subscribe(self, msg_type: type, topic: str) -> None:
        decode = _DECODE[topic]

        def accept(msg: Any) -> dict[str, Any] | None:
            values = decode(msg, self.axes)  # values first: a bad message is a fault even when stale
            return self.matcher.add(topic, stamp_to_ns(msg.header.stamp), values, wall_time_s())

        self.subscribe_checked(msg_type, topic, accept, then=self._step)

    def _step(self, items: dict[str, Any]) -> None:
        stamp_ns = self.matcher.last_released_ns
        assert stamp_ns is not None  # a tick was just released
        estimate = self.estimator.step(items["reference"], items["joint_states"])
        self.publisher.publish(estimate_to_msg(estimate, self.axes, stamp_ns, self.settings.method))

    def _watchdog(self) -> None:
        overdue = self.matcher.overdue(wall_time_s())
        if overdue is not None:
            stamp_ns, missing = overdue
            topics = ", ".join(self.resolve_topic_name(name) for name in missing)
            self.fault(f"estimator: no {topics} for tick t={stamp_ns / NS_PER_S:.6f} s "
                       f"within {self.matcher.current_timeout_s} s")


#: Each input decoded and checked on arrival (a fault names the field).
_DECODE: dict[str, Callable[[Any, Any], Any]] = {
    "joint_states": lambda msg, axes: joint_positions(msg, axes)[0],
    "reference": reference_positions,
}


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_contour_control estimator --ros-args -p program_file:=part.yaml``."""
    raise SystemExit(spin_node(EstimatorNode, args))
