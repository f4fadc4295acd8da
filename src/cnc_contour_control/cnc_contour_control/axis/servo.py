"""The per-axis position servo: feedback law + feedforward + compensation, saturated and quantised.

One sample::

    error_m     = ref_position_m − position_m
    feedback    = law.step(sample)            sample: error, position, velocity, references in counts,
                                                      dt_s, the previously applied command
    feedforward = ff1 · v_ref · counts_per_m + ff2 · a_ref · counts_per_m
    total       = feedback + feedforward + compensation
    command     = quantise(total, quantum, output_limit)   clip to ±limit, round, never beyond the limit

Everything after ``error_m`` is in the law's units: length in counts (BLU for
paper 000, ``counts_per_m = 1e5``), command in drive units (DAC for paper
000, whose 8-bit DAC gives ``output_limit = 127`` and ``quantum = 1``).
Quantisation rounds half away from zero; a quantised value beyond the limit
(when the limit is not a multiple of the quantum) steps back one quantum. The
command of one sample is the law's ``applied_command`` in the next.

The servo commands the spindle, so it knows its speed: with a spindle
schedule (``spindle_schedule_t_s``, ``spindle_schedule_rpm``) the engine
stage and the node call :meth:`ServoController.follow_spindle` with each
tick's stamp before the sample, and a law that follows the spindle
(:class:`~cnc_contour_control.laws.base.SpindleFollowing`: paper 002's PDC)
redesigns when the speed changes; a refused speed keeps the last design.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.axis.spindle_follower import SpindleFollower, spindle_schedule
from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.laws import LAWS, FeedbackLaw, LawSample, law_config, make_law
from cnc_contour_control.laws.base import SpindleFollowing

#: Largest feedforward gain a config accepts [drive units per count/s or count/s²].
MAX_FEEDFORWARD = 1.0e6


#: The following-error trip is on by default, as a machine has it (LinuxCNC always has one): the bound is
#: 2 mm at rest plus 0.5 s of the reference's travel, 2 mm + 0.5 s · |v_ref|. Over the shipped scenarios the
#: largest following error is 39 % of this bound (fidelity circle at 5 m/min, accelerating); a loop gone unstable
#: (gains in the wrong units) trips it within a fraction of a second.
DEFAULT_MIN_FERROR_M = 2.0e-3
#: Added at ``ferror_velocity_m_s`` = 1 m/s, i.e. 0.5 s · |v_ref| (see :data:`DEFAULT_MIN_FERROR_M`).
DEFAULT_FERROR_M = 0.5
#: Servo keys that switch the trip off: for studies of a loop's own behaviour (a reading whose loop diverges, a
#: learning rate that makes it ring), never for a machine run.
NO_FERROR_TRIP = {"min_ferror_m": 0.0, "ferror_m": 0.0}


@dataclass(frozen=True)
class ServoConfig:
    """Validated configuration of one axis's servo.

    Parameters
    ----------
    axis_name : str
        The axis this servo drives.
    law : str
        Feedback law name in :data:`cnc_contour_control.laws.LAWS`.
    law_params : Mapping
        Gains of the law: keys of its config class (``law_config_class(law)``), validated by building it.
    counts_per_m : float
        Law length units per metre (BLU: 1e5), in [1e-3, 1e12].
    ff1 : float
        Velocity feedforward [drive units per (count/s)] of the reference velocity, in [-1e6, 1e6].
    ff2 : float
        Acceleration feedforward [drive units per (count/s²)], in [-1e6, 1e6].
    output_limit : float
        Symmetric saturation of the command [drive units], in [1e-9, 1e12].
    quantum : float
        Command resolution [drive units], in [0, 1e6] (0: no quantisation).
    command_unit : str
        Name of the drive unit (``"dac"``).
    min_ferror_m, ferror_m : float
        Following-error trip bounds [m], each in [0, 1]; both 0: no trip (:mod:`cnc_contour_control.axis.safety`).
        On by default: 2 mm + 0.5 s · |v_ref| (:data:`DEFAULT_MIN_FERROR_M`, :data:`DEFAULT_FERROR_M`).
    ferror_velocity_m_s : float
        Velocity at which ``ferror_m`` is added [m/s], in [1e-6, 1e3].
    spindle_schedule_t_s : tuple of float
        Times the commanded spindle speed changes [s], >= 0, increasing (empty: the law keeps its design).
    spindle_schedule_rpm : tuple of float
        The commanded spindle speed from each of those times on [rpm], > 0, one per time.
    """

    axis_name: str = param(description="axis this servo drives", read_only=True)
    law: str = param("pid", description=f"feedback law, one of {sorted(LAWS)}", read_only=True)
    law_params: Mapping[str, Any] = param(default_factory=dict, description="the law's gains (its config's keys)")
    counts_per_m: float = param(1.0e5, unit="count/m", low=1.0e-3, high=1.0e12, read_only=True,
                                description="law length units per metre (1e5: BLU of 10 um)")
    ff1: float = param(0.0, unit="drive/(count/s)", low=-MAX_FEEDFORWARD, high=MAX_FEEDFORWARD,
                       description="velocity feedforward of the reference velocity")
    ff2: float = param(0.0, unit="drive/(count/s^2)", low=-MAX_FEEDFORWARD, high=MAX_FEEDFORWARD,
                       description="acceleration feedforward of the reference acceleration")
    output_limit: float = param(127.0, unit="drive", low=1.0e-9, high=1.0e12, read_only=True,
                                description="symmetric saturation of the command")
    quantum: float = param(1.0, unit="drive", low=0.0, high=1.0e6, read_only=True,
                           description="command resolution (0: no quantisation)")
    command_unit: str = param("dac", description="name of the drive unit (dac, V, N)", read_only=True)
    min_ferror_m: float = param(DEFAULT_MIN_FERROR_M, unit="m", low=0.0, high=1.0,
                                description="following-error trip: bound at rest (LinuxCNC MIN_FERROR; "
                                            "0 with ferror_m 0: no trip), cnc_contour_control.axis.safety")
    ferror_m: float = param(DEFAULT_FERROR_M, unit="m", low=0.0, high=1.0,
                            description="following-error trip: bound added at ferror_velocity_m_s (LinuxCNC FERROR)")
    ferror_velocity_m_s: float = param(1.0, unit="m/s", low=1.0e-6, high=1.0e3,
                                       description="following-error trip: velocity at which ferror_m is added "
                                                   "(the axis's maximum velocity)")
    spindle_schedule_t_s: tuple[float, ...] = param((), unit="s", read_only=True,
                                                    description="times the commanded spindle speed changes")
    spindle_schedule_rpm: tuple[float, ...] = param((), unit="rpm", read_only=True,
                                                    description="commanded spindle speed from each time on")

    def __post_init__(self) -> None:
        for name in ("axis_name", "command_unit"):
            value = getattr(self, name)
            if not isinstance(value, str) or not value:
                raise ConfigError(f"{name} must be a non-empty string, got {value!r}")
        require_choice("law", self.law, LAWS)
        params = {} if self.law_params is None else self.law_params
        if not isinstance(params, Mapping):
            raise ConfigError(f"law_params must be a mapping, got {self.law_params!r}")
        object.__setattr__(self, "law_params", dict(params))
        check_ranges(self)
        self.law_config()
        times, rpms = spindle_schedule(self.spindle_schedule_t_s, self.spindle_schedule_rpm)
        object.__setattr__(self, "spindle_schedule_t_s", times)
        object.__setattr__(self, "spindle_schedule_rpm", rpms)

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], context: str = "servo") -> ServoConfig:
        """Build from a mapping; unknown keys (also in ``law_params``) are an error."""
        return build_config(cls, mapping, context=context)

    def law_config(self) -> Any:
        """The law's validated config (an instance of ``law_config_class(law)``) from ``law_params``."""
        return law_config(self.law, self.law_params)

    def make_law(self) -> FeedbackLaw:
        """A fresh feedback law from ``law`` and ``law_params``."""
        return make_law(self.law, self.law_params)


@dataclass(slots=True)
class ServoOutput:
    """One servo sample and its parts (drive units unless named otherwise); read-only by convention.

    Not frozen: a frozen dataclass costs four times as much to build, and one
    is built per axis and tick (``./dev bench laws``).

    Attributes
    ----------
    command : float
        Saturated, quantised command sent to the drive.
    feedback : float
        The law's output (:attr:`LawOutput.feedback`).
    feedforward : float
        Velocity + acceleration feedforward.
    compensation : float
        The external compensation added.
    disturbance_estimate : float
        The law's disturbance estimate (0 for laws without one).
    saturated : bool
        True when the applied command is at ``output_limit`` (:func:`at_limit`), whichever part clamped it.
    error_m : float
        Following error ``ref − position`` [m].
    """

    command: float
    feedback: float
    feedforward: float
    compensation: float
    disturbance_estimate: float
    saturated: bool
    error_m: float


def quantise(value: float, quantum: float, limit: float = math.inf) -> float:
    """``value`` clipped to ``±limit`` and rounded to a multiple of ``quantum``, never beyond the limit.

    Halves round away from zero; a rounded value beyond the limit (when the
    limit is not a multiple of the quantum) steps back one quantum. ``quantum``
    0: clipped only. The servo runs exactly this on every command.
    """
    if value > limit:
        value = limit
    elif value < -limit:
        value = -limit
    if quantum <= 0.0:
        return value
    steps = math.floor(abs(value) / quantum + 0.5)
    if steps * quantum > limit:
        steps -= 1
    return math.copysign(steps * quantum, value) if steps else 0.0


def at_limit(total: float, command: float, limit: float) -> bool:
    """True when the command is at the limit: the total reached ``±limit``, or the applied command did.

    The law may clamp itself (the PID at ±127), so a total exactly at the limit
    counts; a total beyond it too, even when quantisation stepped the command back.
    """
    return total >= limit or total <= -limit or command >= limit or command <= -limit


#: One servo sample as a tuple:
#: (command, feedback, feedforward, compensation, disturbance_estimate, saturated, error_m).
ServoParts = tuple[float, float, float, float, float, bool, float]

_INPUT_NAMES = ("dt_s", "ref_position_m", "ref_velocity_m_s", "ref_acceleration_m_s2",
                "position_m", "velocity_m_s", "compensation")


class ServoController:
    """Position servo of one axis (see the module docstring for the law of one sample).

    Parameters
    ----------
    config : ServoConfig
        Validated configuration.
    """

    def __init__(self, config: ServoConfig) -> None:
        self.law = config.make_law()
        self._law_step = self.law.step
        self._law_sample = LawSample()
        self.spindle: SpindleFollower | None = None
        if config.spindle_schedule_t_s and isinstance(self.law, SpindleFollowing):
            self.spindle = SpindleFollower(self.law, config.spindle_schedule_t_s, config.spindle_schedule_rpm)
        self._apply(config)

    def _apply(self, config: ServoConfig) -> None:
        self.config = config
        self._counts = float(config.counts_per_m)
        self._ff1 = float(config.ff1)
        self._ff2 = float(config.ff2)
        self._limit = float(config.output_limit)
        self._quantum = float(config.quantum)

    def reset(self) -> None:
        """Reset the law's state and forget the applied command."""
        self.law.reset()
        self._law_sample.applied_command = 0.0

    def retune(self, config: ServoConfig) -> None:
        """Take ``config``'s gains, feedforward and limits keeping the law's state (a run-time change).

        Raises
        ------
        ConfigError
            If ``config`` is for another axis or another law (that needs a new controller).
        """
        old = self.config
        for name in ("axis_name", "law"):
            if getattr(config, name) != getattr(old, name):
                raise ConfigError(f"servo {old.axis_name}: retune keeps {name} {getattr(old, name)!r}, "
                                  f"got {getattr(config, name)!r} (build a new controller)")
        self.law.retune(config.law_config())
        if self.spindle is not None:  # the gains carry the design speed: back to the commanded one
            self.spindle.apply()
        self._apply(config)

    def follow_spindle(self, stamp_ns: int) -> str | None:
        """Give the law the spindle speed commanded at ``stamp_ns`` before the tick's sample.

        Returns the reason a redesign was refused (the law keeps its last valid
        design), else None; without a schedule or a law that follows it, None.
        """
        return None if self.spindle is None else self.spindle.follow(stamp_ns)

    def step(self, dt_s: float, ref_position_m: float, ref_velocity_m_s: float, ref_acceleration_m_s2: float,
             position_m: float, velocity_m_s: float, compensation: float) -> ServoOutput:
        """One sample: references [m, m/s, m/s²], measured position [m] and velocity [m/s] to a command.

        ``compensation`` is in drive units. Raises :class:`FaultError` naming the
        first non-finite input (or a ``dt_s <= 0``); the law's state is untouched then.
        """
        return ServoOutput(*self.parts(dt_s, ref_position_m, ref_velocity_m_s, ref_acceleration_m_s2, position_m,
                                       velocity_m_s, compensation))

    def parts(self, dt_s: float, ref_position_m: float, ref_velocity_m_s: float, ref_acceleration_m_s2: float,
              position_m: float, velocity_m_s: float, compensation: float) -> ServoParts:
        """:meth:`step` as a plain tuple in :class:`ServoOutput`'s field order (the engine's per-tick call).

        (command, feedback, feedforward, compensation, disturbance_estimate, saturated, error_m).
        """
        checksum = (dt_s + ref_position_m + ref_velocity_m_s + ref_acceleration_m_s2 + position_m + velocity_m_s
                    + compensation)
        if checksum - checksum != 0.0 or dt_s <= 0.0:  # a NaN or an infinity among the inputs (or an overflow)
            self._check_inputs((dt_s, ref_position_m, ref_velocity_m_s, ref_acceleration_m_s2, position_m,
                                velocity_m_s, compensation))
        counts, sample = self._counts, self._law_sample
        error_m = ref_position_m - position_m
        sample.dt_s = dt_s
        sample.error_counts = error_m * counts
        sample.position_counts = position_m * counts
        sample.velocity_counts_s = velocity_m_s * counts
        sample.ref_velocity_counts_s = ref_v = ref_velocity_m_s * counts
        sample.ref_acceleration_counts_s2 = ref_a = ref_acceleration_m_s2 * counts
        out = self._law_step(sample)
        feedforward = self._ff1 * ref_v + self._ff2 * ref_a
        total = out.feedback + feedforward + compensation
        limit = self._limit
        command = quantise(total, self._quantum, limit)
        sample.applied_command = command
        return (command, out.feedback, feedforward, compensation, out.disturbance_estimate,
                at_limit(total, command, limit), error_m)

    def command(self, dt_s: float, ref_position_m: float, ref_velocity_m_s: float, ref_acceleration_m_s2: float,
                position_m: float, velocity_m_s: float, compensation: float) -> float:
        """:meth:`step`'s command alone (the same computation)."""
        return self.parts(dt_s, ref_position_m, ref_velocity_m_s, ref_acceleration_m_s2, position_m, velocity_m_s,
                          compensation)[0]

    def _check_inputs(self, values: tuple[float, ...]) -> None:
        """Raise :class:`FaultError` naming the first non-finite input, or a ``dt_s <= 0``."""
        for name, value in zip(_INPUT_NAMES, values):
            if not math.isfinite(value):
                raise FaultError(
                    f"servo {self.config.axis_name}: {name} must be finite, got {value!r}"
                )
        if values[0] <= 0.0:
            raise FaultError(f"servo {self.config.axis_name}: dt_s must be > 0, got {values[0]!r}")
