"""The seam of the force regulators: the law protocol and the checks of one sample (ROS-free).

A force law turns the measured cutting force and its reference [N] into a
requested feed-override ratio (1.0 = programmed feed). The regulator
(:mod:`.regulator`) quantises it and tells the law what was applied
(``note_applied``), so a law with state winds up no further than the CNC went.
A preview from the part program sets the law's depth estimate ahead of the
tool (``set_depth_mm``).
"""
from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

from cnc_contour_control.core.errors import ConfigError, FaultError


@runtime_checkable
class ForceLaw(Protocol):
    """What every force law offers."""

    def reset(self, ratio: float = 1.0) -> None:
        """Forget the past; the last applied ratio is ``ratio``."""

    def step(self, dt_s: float, force_n: float, reference_n: float) -> float:
        """One update ``dt_s`` [s] after the last: measured ``force_n`` [N], ``reference_n`` [N] -> requested ratio."""

    def note_applied(self, ratio: float) -> None:
        """The ratio the CNC applied after this update's request (quantised, clipped)."""

    def set_depth_mm(self, depth_mm: float) -> None:
        """The depth of cut [mm] the law should assume from now on (a preview from the program)."""


def check_sample(dt_s: float, force_n: float, reference_n: float) -> None:
    """Refuse a bad sample: ``dt_s`` not > 0 or ``reference_n`` not > 0 (ConfigError), non-finite force (FaultError)."""
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise ConfigError(f"dt_s must be finite and > 0, got {dt_s!r}")
    if not (math.isfinite(reference_n) and reference_n > 0.0):
        raise ConfigError(f"reference_n must be finite and > 0, got {reference_n!r}")
    if not math.isfinite(force_n):
        raise FaultError(f"force_n must be finite, got {force_n!r}")


def sat(value: float) -> float:
    """Eq. 11's saturation: ``value`` clipped to [−1, 1]."""
    return -1.0 if value < -1.0 else (1.0 if value > 1.0 else value)
