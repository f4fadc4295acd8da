"""The per-axis position servo: feedback law + feedforward + compensation, saturated and quantised.

One sample::

    error_m     = ref_position_m − position_m
    feedback    = law.step(error_m · counts_per_m, dt_s)
    feedforward = ff1 · v_ref · counts_per_m + ff2 · a_ref · counts_per_m
    total       = feedback + feedforward + compensation
    command     = quantise(clip(total, ±output_limit), quantum)

Everything after ``error_m`` is in the law's units: length in counts (BLU for
paper 000, ``counts_per_m = 1e5``), command in drive units (DAC for paper
000, whose 8-bit DAC gives ``output_limit = 127`` and ``quantum = 1``).
Quantisation rounds half away from zero; a quantised value beyond the limit
(when the limit is not a multiple of the quantum) steps back one quantum.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from cnc_contour_control.config import (
    build_config,
    require_choice,
    require_finite,
    require_non_negative,
    require_positive,
)
from cnc_contour_control.errors import ConfigError, FaultError
from cnc_contour_control.laws import LAWS, FeedbackLaw, make_law


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
        Params of the law (validated by building it).
    counts_per_m : float
        Law length units per metre (BLU: 1e5), > 0.
    ff1 : float
        Velocity feedforward [drive units per (count/s)] of the reference velocity.
    ff2 : float
        Acceleration feedforward [drive units per (count/s²)].
    output_limit : float
        Symmetric saturation of the command [drive units], > 0.
    quantum : float
        Command resolution [drive units], >= 0 (0: no quantisation).
    command_unit : str
        Name of the drive unit (``"dac"``).
    """

    axis_name: str
    law: str = "pid"
    law_params: Mapping[str, Any] = field(default_factory=dict)
    counts_per_m: float = 1.0e5
    ff1: float = 0.0
    ff2: float = 0.0
    output_limit: float = 127.0
    quantum: float = 1.0
    command_unit: str = "dac"

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
        require_positive("counts_per_m", self.counts_per_m)
        require_finite("ff1", self.ff1)
        require_finite("ff2", self.ff2)
        require_positive("output_limit", self.output_limit)
        require_non_negative("quantum", self.quantum)
        self.make_law()

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], context: str = "servo") -> ServoConfig:
        """Build from a mapping; unknown keys (also in ``law_params``) are an error."""
        return build_config(cls, mapping, context=context)

    def make_law(self) -> FeedbackLaw:
        """A fresh feedback law from ``law`` and ``law_params``."""
        return make_law(self.law, self.law_params)


@dataclass(frozen=True, slots=True)
class ServoOutput:
    """One servo sample and its parts (drive units unless named otherwise).

    Attributes
    ----------
    command : float
        Saturated, quantised command sent to the drive.
    feedback : float
        The law's output.
    feedforward : float
        Velocity + acceleration feedforward.
    compensation : float
        The external compensation added.
    disturbance_estimate : float
        The law's disturbance estimate (0 for laws without one).
    saturated : bool
        True when the unsaturated total exceeded ``output_limit``.
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


def quantise(value: float, quantum: float) -> float:
    """Round ``value`` to a multiple of ``quantum``, halves away from zero (``quantum`` 0: unchanged)."""
    if quantum <= 0.0:
        return value
    steps = math.floor(abs(value) / quantum + 0.5)
    return math.copysign(steps * quantum, value) if steps else 0.0


_INPUT_NAMES = ("dt_s", "ref_position_m", "ref_velocity_m_s", "ref_acceleration_m_s2",
                "position_m", "compensation")


class ServoController:
    """Position servo of one axis (see the module docstring for the law of one sample).

    Parameters
    ----------
    config : ServoConfig
        Validated configuration.
    """

    def __init__(self, config: ServoConfig) -> None:
        self.config = config
        self.law = config.make_law()
        self._counts = float(config.counts_per_m)
        self._ff1 = float(config.ff1) * self._counts
        self._ff2 = float(config.ff2) * self._counts
        self._limit = float(config.output_limit)
        self._quantum = float(config.quantum)
        self._max_steps = math.floor(self._limit / self._quantum) if self._quantum > 0 else 0
        self._has_estimate = hasattr(self.law, "disturbance_estimate")

    def reset(self) -> None:
        """Reset the law's state."""
        self.law.reset()

    def step(
        self,
        dt_s: float,
        ref_position_m: float,
        ref_velocity_m_s: float,
        ref_acceleration_m_s2: float,
        position_m: float,
        compensation: float = 0.0,
    ) -> ServoOutput:
        """One sample: references [m, m/s, m/s²] and measured position [m] to a command.

        ``compensation`` is in drive units. Raises :class:`FaultError` naming the
        first non-finite input (or a ``dt_s <= 0``); the law's state is untouched then.
        """
        command, feedback, feedforward, saturated, error_m = self._sample(
            dt_s, ref_position_m, ref_velocity_m_s, ref_acceleration_m_s2, position_m, compensation)
        estimate = self.law.disturbance_estimate if self._has_estimate else 0.0  # type: ignore[attr-defined]
        return ServoOutput(command, feedback, feedforward, compensation, estimate, saturated, error_m)

    def command(
        self,
        dt_s: float,
        ref_position_m: float,
        ref_velocity_m_s: float,
        ref_acceleration_m_s2: float,
        position_m: float,
        compensation: float = 0.0,
    ) -> float:
        """:meth:`step`'s command alone (same arithmetic, same state update), for the in-process engine."""
        return self._sample(dt_s, ref_position_m, ref_velocity_m_s, ref_acceleration_m_s2,
                            position_m, compensation)[0]

    def _sample(self, dt_s: float, ref_position_m: float, ref_velocity_m_s: float,
                ref_acceleration_m_s2: float, position_m: float,
                compensation: float) -> tuple[float, float, float, bool, float]:
        """(command, feedback, feedforward, saturated, error_m) of one sample; updates the law."""
        checksum = dt_s + ref_position_m + ref_velocity_m_s + ref_acceleration_m_s2 + position_m + compensation
        if checksum - checksum != 0.0 or dt_s <= 0.0:  # a NaN or an infinity among the inputs (or an overflow)
            self._check_inputs((dt_s, ref_position_m, ref_velocity_m_s, ref_acceleration_m_s2,
                                position_m, compensation))
        error_m = ref_position_m - position_m
        feedback = self.law.step(error_m * self._counts, dt_s)
        feedforward = self._ff1 * ref_velocity_m_s + self._ff2 * ref_acceleration_m_s2
        total = feedback + feedforward + compensation
        saturated = abs(total) > self._limit
        command = math.copysign(self._limit, total) if saturated else total
        quantum = self._quantum
        if quantum > 0.0:  # quantise the saturated value, keeping it within the limit
            steps = min(math.floor(abs(command) / quantum + 0.5), self._max_steps)
            command = math.copysign(steps * quantum, command) if steps else 0.0
        return command, feedback, feedforward, saturated, error_m

    def _check_inputs(self, values: tuple[float, ...]) -> None:
        """Raise :class:`FaultError` naming the first non-finite input, or a ``dt_s <= 0``."""
        for name, value in zip(_INPUT_NAMES, values):
            if not math.isfinite(value):
                raise FaultError(
                    f"servo {self.config.axis_name}: {name} must be finite, got {value!r}"
                )
        if values[0] <= 0.0:
            raise FaultError(f"servo {self.config.axis_name}: dt_s must be > 0, got {values[0]!r}")
