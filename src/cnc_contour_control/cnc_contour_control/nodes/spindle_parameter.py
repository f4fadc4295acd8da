"""The live ``spindle_rpm`` parameter of a node: declared, validated by its receiver, refusals on /diagnostics."""
from __future__ import annotations

from collections.abc import Callable

from diagnostic_msgs.msg import DiagnosticStatus
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter

from cnc_contour_control.axis.spindle_override import (
    SPINDLE_RPM_DESCRIPTION,
    SPINDLE_RPM_PARAMETER,
    SPINDLE_RPM_RANGE,
    SpindleOverride,
)
from cnc_contour_control.nodes.common import SuiteNode, describe


def watch_spindle_rpm(node: SuiteNode, receiver: Callable[[float], object], who: str) -> SpindleOverride:
    """Declare ``spindle_rpm`` (0: no override) on ``node``; each set goes to ``receiver`` or is refused.

    A refusal answers the set with the reason and publishes it as a WARN on /diagnostics (``who`` names the
    node's part: ``servo x``, ``plant``); the receiver keeps its last valid speed.
    """
    override = SpindleOverride(receiver)
    descriptor = describe(SPINDLE_RPM_DESCRIPTION, *SPINDLE_RPM_RANGE)
    descriptor.dynamic_typing = True  # ``ros2 param set ... spindle_rpm 1650`` sends an integer (a second
    # pre-set callback to retype it would duplicate every parameter: rclpy concatenates their lists)
    node.declare(SPINDLE_RPM_PARAMETER, 0.0, descriptor)

    def on_set(parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name != SPINDLE_RPM_PARAMETER:
                continue
            reason = override.set(parameter.value)
            if reason is not None:
                node.report(DiagnosticStatus.WARN, f"{who}: {reason}",
                            {SPINDLE_RPM_PARAMETER: str(parameter.value), "kept_rpm": str(override.rpm or 0.0)})
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(on_set)
    return override
