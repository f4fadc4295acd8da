"""Messages to arrays and back for the plant node (the package's one conversions module)."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.core.lockstep import require_finite_values
from cnc_contour_control.nodes.common import ns_to_stamp, set_stamp
from cnc_contour_control.nodes.fast_cdr import constructor
from cnc_contour_interfaces.msg import AxisCommand
from cnc_plant_sim.process.cutting import TOOL_FRAME

#: New per-tick messages at their defaults, as ``JointState()`` and ``Clock()`` give them (without their checks).
_new_joint_state = constructor(JointState)
_new_clock = constructor(Clock)


def joint_state_msg(axes: Sequence[str], positions_m: Sequence[float] | np.ndarray, velocities_m_s: Sequence[float],
                    stamp_ns: int) -> JointState:
    """Axis positions [m] and velocities [m/s] to a JointState stamped ``stamp_ns``."""
    msg = _new_joint_state()
    set_stamp(msg.header.stamp, stamp_ns)
    msg.header.frame_id = "machine"
    msg.name = list(axes)
    msg.position = list(map(float, positions_m))
    msg.velocity = list(map(float, velocities_m_s))
    return msg


def wrench_msg(force_n: float, stamp_ns: int) -> WrenchStamped:
    """The main cutting force F_c [N] as a ``cutting_force`` wrench: ``force.x`` in frame ``tool``, the rest 0."""
    msg = WrenchStamped()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = TOOL_FRAME
    msg.wrench.force.x = float(force_n)
    return msg


def clock_msg(stamp_ns: int) -> Clock:
    """Simulation time to a /clock message."""
    msg = _new_clock()
    set_stamp(msg.clock, stamp_ns)
    return msg


def command_value(msg: AxisCommand, axis: str) -> float:
    """The command of ``axis``; faults on a wrong axis or a non-finite value (never applied)."""
    if msg.axis_name != axis:
        raise FaultError(f"servo/{axis}/command carries axis {msg.axis_name!r}")
    require_finite_values((msg.command,), f"servo/{axis}/command.command")
    return float(msg.command)


def joint_command_values(msg: JointState, axes: Sequence[str], field: str) -> dict[str, float]:
    """The commands a JointState carries in ``field`` (effort or velocity), by axis; faults on bad data.

    ``msg.name`` may hold some of ``axes`` (never another name, never one twice), one value each.
    """
    names = list(msg.name)
    values = list(getattr(msg, field))
    unknown = [name for name in names if name not in axes]
    if unknown:
        raise FaultError(f"joint_commands.name has unknown joints {unknown} (the plant's axes: {list(axes)})")
    if len(set(names)) != len(names):
        raise FaultError(f"joint_commands.name repeats a joint: {names}")
    if len(values) != len(names):
        raise FaultError(f"joint_commands.{field} has {len(values)} values for {len(names)} names")
    require_finite_values(values, f"joint_commands.{field}")
    return {name: float(value) for name, value in zip(names, values)}
