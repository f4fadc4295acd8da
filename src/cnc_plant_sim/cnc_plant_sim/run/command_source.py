"""Where the plant's commands come from, and which JointState field carries them (ROS-free).

``axis_command`` (the default): one ``cnc_contour_interfaces/AxisCommand`` per
axis and tick on ``servo/<axis>/command``, as the suite's servos publish.

``joint_state``: ``sensor_msgs/JointState`` on ``joint_commands``, as
topic-based ros2_control hardware takes commands: ``name`` are the plant's
axis names (a message may carry some of them; every axis must arrive once per
tick), ``header.stamp`` is the tick's stamp (lockstep: the stamp of the
``joint_states`` it answers), and the command sits in the field of the
plant's command interface, chosen by the plant's command unit:

=========  ==================  ==========  =====================================
unit       plants              field       meaning
=========  ==================  ==========  =====================================
``dac``    paper000, custom    effort      the drive's input (DAC counts: torque)
``N``      paper001            effort      force on the axis [N]
``m/s``    paper002, paper003  velocity    velocity set-point of the inner loop
=========  ==================  ==========  =====================================

The value is applied exactly as an AxisCommand's ``command`` would be.
"""
from __future__ import annotations

from dataclasses import dataclass

from cnc_contour_control.core.config import require_choice, require_name
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param

__all__ = ["COMMAND_INTERFACES", "COMMAND_SOURCES", "CommandSourceParams", "command_interface"]

#: The plant's command sources.
COMMAND_SOURCES = ("axis_command", "joint_state")
#: The JointState field carrying a command, by the plant's command unit (ros2_control's command interface).
COMMAND_INTERFACES: dict[str, str] = {"dac": "effort", "N": "effort", "m/s": "velocity"}


@dataclass(frozen=True)
class CommandSourceParams:
    """The plant node's command source (run parameters, read-only)."""

    command_source: str = param("axis_command", read_only=True,
                                description=f"where the commands come from, one of {list(COMMAND_SOURCES)}: "
                                            "servo/<axis>/command (AxisCommand) or a sensor_msgs/JointState "
                                            "on joint_command_topic (effort or velocity by the plant's unit)")
    joint_command_topic: str = param("joint_commands", read_only=True,
                                     description="topic of the JointState commands (command_source joint_state)")

    def __post_init__(self) -> None:
        require_choice("command_source", self.command_source, COMMAND_SOURCES)
        require_name("joint_command_topic", self.joint_command_topic)
        check_ranges(self)


def command_interface(command_unit: str) -> str:
    """The JointState field (``effort`` or ``velocity``) carrying commands in ``command_unit``."""
    field = COMMAND_INTERFACES.get(command_unit)
    if field is None:
        raise ConfigError(f"command_source joint_state: no JointState field for the plant's command unit "
                          f"{command_unit!r}; known units: {sorted(COMMAND_INTERFACES)}")
    return field
