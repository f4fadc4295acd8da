"""Interpolator node: part program -> per-axis reference every tick, and the latched path."""
from __future__ import annotations

import math
from typing import Any

from cnc_contour_interfaces.msg import Path, Reference
from sensor_msgs.msg import JointState

from cnc_contour_control.errors import ConfigError
from cnc_contour_control.interpolation import AxisLimits, Interpolator, InterpolatorConfig
from cnc_contour_control.lockstep import StampMatcher, ns_to_s, stamp_horizon_ns
from cnc_contour_control.nodes.common import (
    LATCHED_QOS,
    SuiteNode,
    spin_node,
    stamp_to_ns,
    wall_time_s,
)
from cnc_contour_control.nodes.conversions import joint_positions, program_to_path, reference_to_msg
from cnc_contour_control.nodes.parameters import declare_config
from cnc_contour_control.program_file import read_program_file
from cnc_contour_control.stage_params import InterpolatorRunParams

#: Axis limits of a node started without them: 6000 mm/min and 1000 mm/s^2 on every axis.
DEFAULT_MAX_VELOCITY_M_S = 0.1
DEFAULT_MAX_ACCELERATION_M_S2 = 1.0


class InterpolatorNode(SuiteNode):
    """Publishes ``reference`` for each ``joint_states`` tick and ``path`` once (latched)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("interpolator", **kwargs)
        run = declare_config(self, InterpolatorRunParams)
        self.axes, self.frame_id = run.axes, run.frame_id
        self.interpolator = self._make_interpolator(run.program_file)
        self.reference_pub = self.gated_publisher(Reference, "reference", 1)
        path_pub = self.create_publisher(Path, "path", LATCHED_QOS)
        path_pub.publish(
            program_to_path(self.interpolator.program, 0, self.frame_id, self.interpolator.duration_s)
        )
        # No watchdog: every joint state is answered at once; the matcher checks stamps (from t = 0).
        self.matcher = StampMatcher(("joint_states",), math.inf, max_ahead_ns=stamp_horizon_ns())
        self.matcher.expect(0, wall_time_s())
        self.subscribe_checked(JointState, "joint_states", self._accept, then=self.on_tick)

    def _make_interpolator(self, program_file: str) -> Interpolator:
        """The program's interpolator with the declared limits (config units: m/s, m/s^2) and options."""
        config = declare_config(self, InterpolatorConfig)
        n_axes = len(self.axes)
        limits = declare_config(self, AxisLimits, defaults={
            "max_velocity_m_s": [DEFAULT_MAX_VELOCITY_M_S] * n_axes,
            "max_acceleration_m_s2": [DEFAULT_MAX_ACCELERATION_M_S2] * n_axes})
        program = read_program_file(program_file, self.axes)
        if tuple(program.axis_names) != self.axes:
            raise ConfigError(f"program axes {list(program.axis_names)} differ from parameter axes {list(self.axes)}")
        return Interpolator(program, limits, config)

    def _accept(self, msg: JointState) -> JointState | None:
        """A joint state's values, then its stamp, checked; None for a stale one."""
        joint_positions(msg, self.axes)
        return None if self.matcher.add("joint_states", stamp_to_ns(msg.header.stamp), msg, wall_time_s()) is None else msg

    def on_tick(self, msg: JointState) -> None:
        """One tick: the reference at the joint state's stamp."""
        stamp_ns = stamp_to_ns(msg.header.stamp)
        sample = self.interpolator.reference(ns_to_s(stamp_ns))
        self.reference_pub.publish(reference_to_msg(sample, self.axes, stamp_ns, self.frame_id))


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_contour_control interpolator``."""
    raise SystemExit(spin_node(InterpolatorNode, args))
