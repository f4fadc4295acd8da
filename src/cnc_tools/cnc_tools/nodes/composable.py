"""The node classes a composed process can host, by the (package, executable) that starts each alone.

One explicit list: a :class:`~cnc_tools.runs.graph_nodes.NodeSpec` names a node
by its package and executable (what ``ros2 run`` starts); the composed host
(:mod:`cnc_tools.nodes.composed_host`) builds the same class from here. Classes
are named as ``module:Class`` and imported only when a host builds one, so the
runner can check a run's nodes without importing rclpy.
"""
from __future__ import annotations

import importlib
from typing import Any

from cnc_contour_control.core.config import require_choice

#: (package, executable) -> ``module:Class`` of the node that executable spins.
NODE_CLASSES: dict[tuple[str, str], str] = {
    ("cnc_plant_sim", "plant"): "cnc_plant_sim.nodes.plant_node:PlantNode",
    ("cnc_contour_control", "interpolator"): "cnc_contour_control.nodes.interpolator_node:InterpolatorNode",
    ("cnc_contour_control", "estimator"): "cnc_contour_control.nodes.estimator_node:EstimatorNode",
    ("cnc_contour_control", "compensator"): "cnc_contour_control.nodes.compensator_node:CompensatorNode",
    ("cnc_contour_control", "servo"): "cnc_contour_control.nodes.servo_node:ServoNode",
    ("cnc_contour_control", "force_regulator"): "cnc_contour_control.nodes.force_regulator_node:ForceRegulatorNode",
    ("cnc_tools", "recorder"): "cnc_tools.nodes.recorder_node:RecorderNode",
}


def executable_key(package: str, executable: str) -> str:
    """``package/executable``, the name a registry entry is known by in errors."""
    return f"{package}/{executable}"


def check_composable(package: str, executable: str) -> str:
    """The ``module:Class`` of a node; a ConfigError listing the composable executables for an unknown one."""
    known = {executable_key(*key): path for key, path in NODE_CLASSES.items()}
    return known[require_choice("composed node executable", executable_key(package, executable), known)]


def node_class(package: str, executable: str) -> type[Any]:
    """The node class ``package/executable`` spins (imported now)."""
    module, _, name = check_composable(package, executable).partition(":")
    return getattr(importlib.import_module(module), name)
