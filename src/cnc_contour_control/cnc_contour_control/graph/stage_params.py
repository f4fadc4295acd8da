"""What a stage's node needs besides its algorithm's config: its run parameters (ROS-free).

A node of the graph declares two kinds of ROS parameters, both from config
classes (:mod:`cnc_contour_control.core.params`): its algorithm's config
(``ServoConfig``, ``InterpolatorConfig`` and ``AxisLimits``, ``PlantConfig``)
and one of the classes here (axis, sample time, timeouts, files). Every field
declares unit, range and description with :func:`param`, and ``__post_init__``
validates against exactly those ranges (:func:`check_ranges`), so the runner,
which builds these before it starts a process, refuses what a node would
refuse. All are read-only: a change needs a restart.

The readers a stage waits for before it publishes (``min_subscribers``,
``required_readers``) are declared by the node's gated publisher
(:mod:`cnc_contour_control.nodes.common`), not here.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from cnc_contour_control.axis.servo import ServoConfig
from cnc_contour_control.core.config import require_choice, require_flag, require_name, require_names
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.lockstep import MAX_SAMPLE_TIME_NS, NS_PER_S
from cnc_contour_control.core.params import check_ranges, config_values, param
from cnc_contour_control.motion.feed_override import FEED_OVERRIDE_SOURCES

#: The sample times a node accepts [s].
SAMPLE_TIME_RANGE_S = (1.0e-5, MAX_SAMPLE_TIME_NS / NS_PER_S)
#: Wall-time limits of a tick's wait [s] (per tick, and for the first tick with discovery).
TIMEOUT_RANGE_S = (0.01, 3600.0)


#: The servo node declares ServoConfig's fields but two: the axis is its run parameter ``axis``, and the
#: law's params are the nested parameters ``gains.<key>`` (the fields of the law's config class).
SERVO_GAINS = "gains"
SERVO_NODE_SKIPS = ("axis_name", "law_params")


def servo_config_values(config: ServoConfig) -> dict[str, Any]:
    """A ServoConfig as the servo node's parameters, in the config's units (law params as ``gains``)."""
    values = config_values(config)
    del values["axis_name"]
    values[SERVO_GAINS] = values.pop("law_params")
    return values


def require_startup_after(timeout_s: float, startup_s: float, timeout_name: str) -> None:
    """The first tick may wait at least as long as any other (``startup_timeout_s >= timeout``)."""
    if startup_s < timeout_s:
        raise ConfigError(f"startup_timeout_s must be >= {timeout_name} ({timeout_s}), got {startup_s!r}")


@dataclass(frozen=True)
class LockstepInputs:
    """What every stage that waits for its inputs each tick declares: the sample time and the two timeouts."""

    sample_time_s: float = param(0.01, unit="s", low=SAMPLE_TIME_RANGE_S[0], high=SAMPLE_TIME_RANGE_S[1],
                                 read_only=True, description="nominal sample time T, the dt of the first tick")
    input_timeout_s: float = param(5.0, unit="s", low=TIMEOUT_RANGE_S[0], high=TIMEOUT_RANGE_S[1], read_only=True,
                                   description="wall time a tick may wait for its inputs before it is a fault")
    startup_timeout_s: float = param(30.0, unit="s", low=TIMEOUT_RANGE_S[0], high=TIMEOUT_RANGE_S[1],
                                     read_only=True,
                                     description="wall time the first tick may wait (graph discovery), "
                                                 ">= input_timeout_s")

    def __post_init__(self) -> None:
        check_ranges(self)
        require_startup_after(self.input_timeout_s, self.startup_timeout_s, "input_timeout_s")


@dataclass(frozen=True)
class ServoRunParams(LockstepInputs):
    """Run parameters of one axis's servo node."""

    axis: str = param("x", read_only=True,
                      description="the axis this servo drives (a name in joint_states and reference)")
    use_compensation: bool = param(False, read_only=True, description="wait for /compensation every tick and add it")

    def __post_init__(self) -> None:
        require_name("axis", self.axis)
        require_flag("use_compensation", self.use_compensation)
        super().__post_init__()


@dataclass(frozen=True)
class InterpolatorRunParams:
    """Run parameters of the interpolator node."""

    axes: tuple[str, ...] = param(("x", "y"), read_only=True,
                                  description="axis names in order, those of the program")
    program_file: str = param("", read_only=True, description="the part program: a YAML program or scenario, "
                                                               "or a G-code file")
    frame_id: str = param("machine", read_only=True, description="frame of the references and the path")
    feed_override_source: str = param("none", read_only=True,
                                      description="where the requested feed override comes from: none, schedule "
                                                  "(feed_override.schedule_*), topic (the latest feed_override), "
                                                  "previous_tick (lockstep: feed_override of tick k-1, waited for)")
    feed_override_timeout_s: float = param(2.5, unit="s", low=TIMEOUT_RANGE_S[0], high=TIMEOUT_RANGE_S[1],
                                           read_only=True,
                                           description="wall time a tick may wait for the previous tick's "
                                                       "feed_override (previous_tick) before it is a fault")

    def __post_init__(self) -> None:
        object.__setattr__(self, "axes", require_names("axes", self.axes))
        if not isinstance(self.program_file, str):
            raise ConfigError(f"program_file must be a path, got {self.program_file!r}")
        require_name("frame_id", self.frame_id)
        require_choice("feed_override_source", self.feed_override_source, FEED_OVERRIDE_SOURCES)
        check_ranges(self)


@dataclass(frozen=True)
class EstimatorRunParams(LockstepInputs):
    """Run parameters of the contour-error estimator node."""

    axes: tuple[str, ...] = param(("x", "y"), read_only=True,
                                  description="axis names in order, those of joint_states and reference")
    program_file: str = param("", read_only=True, description="the part program (as the interpolator reads it); "
                                                               "the path estimator measures against it")

    def __post_init__(self) -> None:
        object.__setattr__(self, "axes", require_names("axes", self.axes))
        if not isinstance(self.program_file, str):
            raise ConfigError(f"program_file must be a path, got {self.program_file!r}")
        super().__post_init__()


@dataclass(frozen=True)
class CompensatorRunParams(LockstepInputs):
    """Run parameters of the compensator node."""

    axes: tuple[str, ...] = param(("x", "y"), read_only=True,
                                  description="axis names in order (one correction each)")
    command_unit: str = param("dac", read_only=True, description="the servos' command unit (the correction's)")

    def __post_init__(self) -> None:
        object.__setattr__(self, "axes", require_names("axes", self.axes))
        require_name("command_unit", self.command_unit)
        super().__post_init__()
