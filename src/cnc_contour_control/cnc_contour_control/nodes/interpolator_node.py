"""Interpolator node: part program -> per-axis reference every tick, and the latched path."""
from __future__ import annotations

from typing import Any

from cnc_contour_interfaces.msg import Path, Reference
from sensor_msgs.msg import JointState

from cnc_contour_control.errors import ConfigError
from cnc_contour_control.interpolation import AxisLimits, Interpolator, InterpolatorConfig
from cnc_contour_control.lockstep import ns_to_s
from cnc_contour_control.nodes.common import (
    LATCHED_QOS,
    LOCKSTEP_QOS,
    SuiteNode,
    describe,
    spin_node,
    stamp_to_ns,
)
from cnc_contour_control.nodes.conversions import joint_positions, program_to_path, reference_to_msg
from cnc_contour_control.program_file import read_program_file
from cnc_contour_control.units import mm_s2_to_m_s2, mm_min_to_m_s


class InterpolatorNode(SuiteNode):
    """Publishes ``reference`` for each ``joint_states`` tick and ``path`` once (latched)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("interpolator", **kwargs)
        self.axes = tuple(self.declare("axes", ["x", "y"], describe("axis names, in order", read_only=True)))
        self.frame_id = self.declare("frame_id", "machine", describe("frame of the references", read_only=True))
        self.interpolator = self._make_interpolator()
        self.reference_pub = self.gated_publisher(Reference, "reference", 1)
        path_pub = self.create_publisher(Path, "path", LATCHED_QOS)
        path_pub.publish(
            program_to_path(self.interpolator.program, 0, self.frame_id, self.interpolator.duration_s)
        )
        self.create_subscription(JointState, "joint_states", self.guarded(self.on_tick), LOCKSTEP_QOS)

    def _make_interpolator(self) -> Interpolator:
        program_file = self.declare("program_file", "", describe("YAML program/scenario or G-code file", read_only=True))
        velocity = self.declare("max_velocity_mm_min", [6000.0], describe("per-axis velocity limit, mm/min", read_only=True))
        accel = self.declare("max_acceleration_mm_s2", [1000.0], describe("per-axis acceleration limit, mm/s^2", read_only=True))
        config = InterpolatorConfig(
            corner_angle_tolerance_deg=self.declare("corner_angle_tolerance_deg", 1e-4, describe("junction angle treated as tangent, deg", 0.0, 10.0, True)),
            arc_centripetal_fraction=self.declare("arc_centripetal_fraction", 0.5, describe("share of acceleration for centripetal use on arcs", 0.01, 0.99, True)),
            clamp_feed=self.declare("clamp_feed", False, describe("slow down instead of refusing a feed above the axis limits", read_only=True)),
        )
        program = read_program_file(program_file, self.axes)
        if tuple(program.axis_names) != self.axes:
            raise ConfigError(f"program axes {list(program.axis_names)} differ from parameter axes {list(self.axes)}")
        limits = AxisLimits(
            max_velocity_m_s=tuple(mm_min_to_m_s(v) for v in _per_axis(velocity, len(self.axes))),
            max_acceleration_m_s2=tuple(mm_s2_to_m_s2(a) for a in _per_axis(accel, len(self.axes))),
        )
        return Interpolator(program, limits, config)

    def on_tick(self, msg: JointState) -> None:
        """One tick: the reference at the joint state's stamp."""
        joint_positions(msg, self.axes)
        stamp_ns = stamp_to_ns(msg.header.stamp)
        sample = self.interpolator.sample(ns_to_s(stamp_ns))
        self.reference_pub.publish(reference_to_msg(sample, self.axes, stamp_ns, self.frame_id))


def _per_axis(values: list[float], n_axes: int) -> list[float]:
    """One value for all axes, or one per axis."""
    return list(values) * n_axes if len(values) == 1 else list(values)


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_contour_control interpolator``."""
    raise SystemExit(spin_node(InterpolatorNode, args))
