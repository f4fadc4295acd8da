"""The law seam: what a feedback law sees each sample, what it returns, and the protocol it keeps.

A feedback law steps on one :class:`LawSample` (the servo fills it in the
law's units: lengths in counts, BLU for paper 000; commands in drive units,
DAC for paper 000) and returns a :class:`LawOutput`::

    sample:  dt_s, error_counts, position_counts, velocity_counts_s,
             ref_velocity_counts_s, ref_acceleration_counts_s2, applied_command
    output:  feedback (drive units, unsaturated), disturbance_estimate (drive units)

``applied_command`` is the command the servo sent in the previous sample,
after saturation and quantisation (what the drive really got): an observer
or an anti-windup needs it. Gains are in time units (per second, seconds),
so a law keeps the same loop at another sample time; each law discretises
with the sample's ``dt_s``.

Both records are mutable slots objects reused every sample (the servo owns
one sample, each law one output): the hot path allocates nothing. A caller
that keeps an output past the next step copies it.
"""
from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.slots import SlotsRecord


class LawSample(SlotsRecord):
    """One sample as a feedback law sees it (law units; see the module docstring).

    Attributes
    ----------
    dt_s : float
        The period since the previous sample [s], > 0.
    error_counts : float
        Following error ``reference − position`` [counts].
    position_counts : float
        Measured position [counts].
    velocity_counts_s : float
        Measured velocity [counts/s].
    ref_velocity_counts_s : float
        Reference velocity [counts/s].
    ref_acceleration_counts_s2 : float
        Reference acceleration [counts/s²].
    applied_command : float
        The previous sample's command after saturation and quantisation [drive units] (0 after a reset).
    """

    __slots__ = ("dt_s", "error_counts", "position_counts", "velocity_counts_s", "ref_velocity_counts_s",
                 "ref_acceleration_counts_s2", "applied_command")

    def __init__(self, dt_s: float = 0.01, error_counts: float = 0.0, position_counts: float = 0.0,
                 velocity_counts_s: float = 0.0, ref_velocity_counts_s: float = 0.0,
                 ref_acceleration_counts_s2: float = 0.0, applied_command: float = 0.0) -> None:
        self.dt_s = dt_s
        self.error_counts = error_counts
        self.position_counts = position_counts
        self.velocity_counts_s = velocity_counts_s
        self.ref_velocity_counts_s = ref_velocity_counts_s
        self.ref_acceleration_counts_s2 = ref_acceleration_counts_s2
        self.applied_command = applied_command


class LawOutput:
    """A law's answer to one sample [drive units].

    Attributes
    ----------
    feedback : float
        The law's output, not yet saturated: what the servo adds to the
        feedforward and the compensation (a law that cancels an estimated
        disturbance includes the cancellation here).
    disturbance_estimate : float
        The law's estimate of the input disturbance (0 for laws without an observer).
    """

    __slots__ = ("feedback", "disturbance_estimate")

    def __init__(self, feedback: float = 0.0, disturbance_estimate: float = 0.0) -> None:
        self.feedback = feedback
        self.disturbance_estimate = disturbance_estimate

    def __repr__(self) -> str:
        return f"LawOutput(feedback={self.feedback!r}, disturbance_estimate={self.disturbance_estimate!r})"


@runtime_checkable
class FeedbackLaw(Protocol):
    """A discrete feedback law with internal state and gains in time units.

    Attributes
    ----------
    config : Any
        The law's validated config (its gains).
    """

    config: Any

    def reset(self) -> None:
        """Clear the internal state (as at start-up)."""

    def step(self, sample: LawSample) -> LawOutput:
        """One sample: the law's output (its own record, overwritten by the next step)."""

    def retune(self, config: Any) -> None:
        """Swap the gains for ``config`` (the law's config class) keeping the internal state."""


@runtime_checkable
class SpindleFollowing(Protocol):
    """The optional hook of a law designed for the spindle speed (paper 002's PDC: f_d = rpm · flutes / 60).

    The servo commands the spindle, so it hands the speed of each tick to a
    law that has this method; a law without it ignores the spindle.
    """

    def set_spindle_rpm(self, spindle_rpm: float) -> bool:
        """Follow ``spindle_rpm`` [rpm]: redesign when it differs from the design's, keeping the filter history.

        Returns True when the law redesigned. Raises :class:`ConfigError` (naming the
        parameter, the bound and the value) when no design exists for it; the law
        keeps its last valid design then.
        """


def require_config(law: str, config: Any, config_class: type) -> Any:
    """Return ``config`` if it is a ``config_class``, else a :class:`ConfigError` naming both."""
    if not isinstance(config, config_class):
        raise ConfigError(f"{law} law needs a {config_class.__name__} to retune, got {type(config).__name__}")
    return config


def spindle_redesign(law_name: str, config: Any, spindle_rpm: float) -> Any | None:
    """``config`` redesigned for ``spindle_rpm`` (a dataclass with a ``spindle_rpm`` field), None for the same speed.

    The new config is built (and so designed and validated) before anything
    changes; a refused speed raises a :class:`ConfigError` naming the law and
    both speeds, and the caller keeps its last valid design.
    """
    from dataclasses import replace

    if spindle_rpm == config.spindle_rpm:
        return None
    try:
        return replace(config, spindle_rpm=spindle_rpm)
    except ConfigError as err:
        raise ConfigError(f"{law_name}: no design for spindle_rpm {spindle_rpm:g}, keeping the one for "
                          f"{config.spindle_rpm:g} rpm: {err}") from err

