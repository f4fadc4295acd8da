"""The CNC's feed-override switch: a requested ratio rounded to its levels and clipped to its range.

Paper 004's FANUC 0T takes a 4-bit override, 0-150 % in 10 % steps (16
levels): ``applied = clip(round(requested / step) · step, low, high)``, half
away from zero; ``step_ratio = 0`` only clips (a continuous override). The
range must contain 1.0 (the programmed feed).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param


@dataclass(frozen=True)
class QuantiserConfig:
    """The override switch (defaults: 4 bits, 0-150 % in 10 % steps).

    Parameters
    ----------
    step_ratio : float
        Level spacing [ratio], in [0, 10] (0: continuous).
    min_ratio, max_ratio : float
        Range [ratio], in [0, 10], min <= 1 <= max.
    """

    step_ratio: float = param(0.1, low=0.0, high=10.0, description="override level spacing (0: continuous)")
    min_ratio: float = param(0.0, low=0.0, high=10.0, description="lowest override")
    max_ratio: float = param(1.5, low=0.0, high=10.0, description="highest override")

    def __post_init__(self) -> None:
        check_ranges(self, "quantiser")
        if not self.min_ratio <= 1.0 <= self.max_ratio:
            raise ConfigError(f"quantiser range [{self.min_ratio}, {self.max_ratio}] must contain 1.0 "
                              "(the programmed feed)")

    @property
    def levels(self) -> int | None:
        """Number of levels in the range (None when continuous)."""
        if self.step_ratio == 0.0:
            return None
        top = math.floor(self.max_ratio / self.step_ratio + 1e-9)
        return top - math.ceil(self.min_ratio / self.step_ratio - 1e-9) + 1


class Quantiser:
    """Requested ratio -> applied ratio (module docstring)."""

    def __init__(self, config: QuantiserConfig) -> None:
        self.config = config

    def __call__(self, requested: float) -> float:
        """The applied ratio for ``requested`` (NaN refused)."""
        if math.isnan(requested):
            raise ConfigError(f"requested ratio must be a number, got {requested!r}")
        cfg = self.config
        value = requested
        if cfg.step_ratio > 0.0:
            levels = math.floor(abs(requested) / cfg.step_ratio + 0.5)
            value = math.copysign(levels * cfg.step_ratio, requested)
        return min(max(value, cfg.min_ratio), cfg.max_ratio)
