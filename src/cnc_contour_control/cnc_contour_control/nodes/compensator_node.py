"""Compensator node: joint state + reference + contour error -> ``compensation`` every tick, learning online.

When the plant announces the end of the run (:data:`~cnc_contour_control.core.topics.RUN_FINISHED`
on ``/diagnostics``), the compensator makes its run-to-run update, writes its
learned state to ``state_out`` (if set), reports it and exits with code 0, so
the next run can start from it (``state_in``).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from cnc_contour_control.compensators import CompensatorSample, compensator_config_class
from cnc_contour_control.core.lockstep import NS_PER_S, StampMatcher, seconds_to_ns, stamp_horizon_ns
from cnc_contour_control.core.topics import DIAGNOSTICS, RUN_FINISHED, RUN_ID_KEY
from cnc_contour_control.graph.cross_axis import CompensatorSettings
from cnc_contour_control.graph.stage_params import CompensatorRunParams
from cnc_contour_control.nodes.common import SuiteNode, spin_node
from cnc_contour_control.nodes.conversions import (
    compensation_to_msg,
    contour_error_values,
    joint_positions,
    reference_positions,
)
from cnc_contour_control.nodes.method_params import method_parameters
from cnc_contour_control.nodes.parameters import declare_config
from cnc_contour_interfaces.msg import Compensation, ContourError, Reference

#: The one method parameter a running compensator takes (the neural network's learning rate).
LIVE_LEARNING_RATE = "params.eta"


class CompensatorNode(SuiteNode):
    """Publishes ``compensation`` for every tick whose joint state, reference and contour error it holds.

    Parameters: :class:`~cnc_contour_control.graph.stage_params.CompensatorRunParams`,
    ``method``, ``state_in``, ``state_out``, ``freeze`` (may change while
    running) and the method's config as ``params.*``
    (:class:`~cnc_contour_control.graph.cross_axis.CompensatorSettings`).
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("compensator", **kwargs)
        run = declare_config(self, CompensatorRunParams)
        self.axes, self.command_unit = run.axes, run.command_unit
        self.sample_time_ns = seconds_to_ns(run.sample_time_s)
        parameters = method_parameters(self, CompensatorSettings, compensator_config_class)
        self.settings: CompensatorSettings = parameters.declare()
        self.compensator = self.settings.make(self.axes, run.sample_time_s)
        parameters.watch(self._retune)
        self.add_on_set_parameters_callback(self._refuse_fixed)
        self.sample = CompensatorSample()
        self.sample.tick = -1
        self.last_stamp_ns: int | None = None
        self._fault_reported = False
        self.matcher = StampMatcher(("joint_states", "reference", "contour_error"), run.input_timeout_s,
                                    run.startup_timeout_s, stamp_horizon_ns(self.sample_time_ns))
        self.publisher = self.gated_publisher(Compensation, "compensation", 1)
        for msg_type, topic in ((JointState, "joint_states"), (Reference, "reference"),
                                (ContourError, "contour_error")):
            decode = _DECODE[topic]
            self.subscribe_matched(self.matcher, msg_type, topic, lambda msg, d=decode: d(msg, self.axes), self._step)  # type: ignore[misc]  # mypy infers no lambda with a default
        self.create_subscription(DiagnosticArray, DIAGNOSTICS.name, self.guarded(self._watch_run_end), 100)
        self.watch_inputs(self.matcher, "compensator")

    def _retune(self, settings: CompensatorSettings) -> None:
        """``freeze`` and the neural network's learning rate ``params.eta`` apply while running (the rest is taken
        at the start)."""
        self.settings = settings
        self.compensator.frozen = settings.freeze
        if settings.method == "neural":
            self.compensator.config = replace(self.compensator.config, eta=settings.params["eta"])

    def _refuse_fixed(self, parameters: list[Parameter]) -> SetParametersResult:
        """Refuse a change of a method parameter the running compensator would not take (all but the neural
        network's ``params.eta``): set and ignored, it would read as applied."""
        live = {LIVE_LEARNING_RATE} if self.settings.method == "neural" else set()
        fixed = sorted(p.name for p in parameters if p.name.startswith("params.") and p.name not in live)
        if not fixed:
            return SetParametersResult(successful=True)
        return SetParametersResult(successful=False, reason=(
            f"{', '.join(fixed)}: taken when the compensator starts; while it runs only freeze"
            f"{' and ' + LIVE_LEARNING_RATE if live else ''} change (start the node with the new value)"))

    def _step(self, items: dict[str, Any]) -> None:
        stamp_ns = self.matcher.last_released_ns
        assert stamp_ns is not None  # a tick was just released
        sample = self.sample
        sample.tick += 1
        sample.dt_s = (self.sample_time_ns if self.last_stamp_ns is None else stamp_ns - self.last_stamp_ns) / NS_PER_S
        sample.position_m, sample.ref_position_m = items["joint_states"], items["reference"]
        sample.contour_error_m, sample.angle_rad, sample.tracking_error_m = items["contour_error"]
        correction = self.compensator.step(sample)
        self.last_stamp_ns = stamp_ns
        learning = not self.compensator.frozen and self.compensator.fault is None
        self.publisher.publish(compensation_to_msg(correction, self.axes, self.command_unit, stamp_ns,
                                                   self.settings.method, learning))
        if self.compensator.fault is not None and not self._fault_reported:
            # the compensation is zeroed and learning stopped; the run goes on but did not run as asked: an ERROR,
            # so the run's verdict is faulted (docs/design.md, verdicts)
            self._fault_reported = True
            self.report(DiagnosticStatus.ERROR, f"compensator: {self.compensator.fault}", stamp_ns=stamp_ns)

    def _watch_run_end(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if status.message == RUN_FINISHED and values.get(RUN_ID_KEY) == self.get_namespace():
                self._finish_run()

    def _finish_run(self) -> None:
        saved = self.settings.finish(self.compensator)
        message = f"compensator: run finished after {self.sample.tick + 1} ticks"
        self.report(DiagnosticStatus.OK, message + (f", state saved to {saved}" if saved else ""))
        self.finished = True  # done: spin_node flushes and exits with 0


#: Each input decoded and checked on arrival (a fault names the field): no NaN ever reaches the compensator.
_DECODE: dict[str, Callable[[Any, Any], Any]] = {
    "joint_states": lambda msg, axes: joint_positions(msg, axes)[0],
    "reference": reference_positions,
    "contour_error": contour_error_values,
}


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_contour_control compensator --ros-args -p method:=neural``."""
    raise SystemExit(spin_node(CompensatorNode, args))
