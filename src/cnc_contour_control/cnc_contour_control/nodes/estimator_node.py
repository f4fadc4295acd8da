"""Estimator node: joint state + reference -> ``contour_error`` every tick (paper 001's model or the path's)."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sensor_msgs.msg import JointState

from cnc_contour_control.core.lockstep import StampMatcher, seconds_to_ns, stamp_horizon_ns
from cnc_contour_control.estimators import estimator_config_class
from cnc_contour_control.graph.cross_axis import EstimatorSettings
from cnc_contour_control.graph.stage_params import EstimatorRunParams
from cnc_contour_control.motion.program_file import read_program_file
from cnc_contour_control.nodes.common import SuiteNode, spin_node
from cnc_contour_control.nodes.conversions import estimate_to_msg, joint_positions, reference_positions
from cnc_contour_control.nodes.method_params import method_parameters
from cnc_contour_control.nodes.parameters import declare_config
from cnc_contour_interfaces.msg import ContourError, Reference


class EstimatorNode(SuiteNode):
    """Publishes ``contour_error`` for every tick whose joint state and reference it holds.

    Parameters: :class:`~cnc_contour_control.graph.stage_params.EstimatorRunParams`,
    ``method`` and the method's config as ``params.*``
    (:class:`~cnc_contour_control.graph.cross_axis.EstimatorSettings`).
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
        for msg_type, topic in ((JointState, "joint_states"), (Reference, "reference")):
            decode = _DECODE[topic]
            self.subscribe_matched(self.matcher, msg_type, topic, lambda msg, d=decode: d(msg, self.axes), self._step)  # type: ignore[misc]  # mypy infers no lambda with a default
        self.watch_inputs(self.matcher, "estimator")

    def _step(self, items: dict[str, Any]) -> None:
        stamp_ns = self.matcher.last_released_ns
        assert stamp_ns is not None  # a tick was just released
        estimate = self.estimator.step(items["reference"], items["joint_states"])
        self.publisher.publish(estimate_to_msg(estimate, self.axes, stamp_ns, self.settings.method))


#: Each input decoded and checked on arrival (a fault names the field).
_DECODE: dict[str, Callable[[Any, Any], Any]] = {
    "joint_states": lambda msg, axes: joint_positions(msg, axes)[0],
    "reference": reference_positions,
}


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_contour_control estimator --ros-args -p program_file:=part.yaml``."""
    raise SystemExit(spin_node(EstimatorNode, args))
