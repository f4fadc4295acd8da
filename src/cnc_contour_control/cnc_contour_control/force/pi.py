"""A plain PI on the cutting force: the everyday baseline (velocity form, state clamped).

One update, e = F_ref − F [N]::

    r ← clip(r + k_p (e − e_prev) + k_i dt e,  0, ratio_max)

The state r is the law's own unquantised ratio, clamped to the switch's range
(anti-windup); it is not rounded (a rounded state would lose every increment
smaller than half a level). It needs no model, so a preview's depth is ignored.
"""
from __future__ import annotations

from dataclasses import dataclass

from cnc_contour_control.core.config import require_positive
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.force.base import check_sample


@dataclass(frozen=True)
class PiConfig:
    """Gains of the force PI (defaults: a loop of about 2 rad/s on the paper's nominal gain, 614 N per ratio).

    Parameters
    ----------
    kp_per_n : float
        Proportional gain [ratio/N], in [0, 1].
    ki_per_n_s : float
        Integral gain [ratio/(N·s)], in [0, 10].
    ratio_max : float
        Clamp of the state [ratio], in [0, 10].
    """

    kp_per_n: float = param(5.0e-4, unit="1/N", low=0.0, high=1.0, description="proportional gain")
    ki_per_n_s: float = param(3.0e-3, unit="1/(N*s)", low=0.0, high=10.0, description="integral gain")
    ratio_max: float = param(1.5, low=0.0, high=10.0, description="clamp of the law's ratio (anti-windup)")

    def __post_init__(self) -> None:
        check_ranges(self, "pi")


class PiLaw:
    """The force PI (module docstring)."""

    def __init__(self, config: PiConfig) -> None:
        self.config = config
        self.ratio = 1.0
        self._error_n: float | None = None

    def reset(self, ratio: float = 1.0) -> None:
        """State at ``ratio``; the first update has no proportional kick."""
        self.ratio, self._error_n = float(ratio), None

    def set_depth_mm(self, depth_mm: float) -> None:
        """Checked, then ignored: the PI has no model."""
        require_positive("depth_mm", depth_mm)

    def note_applied(self, ratio: float) -> None:
        """Nothing: the state is clamped to [0, ratio_max] (set it to the switch's range)."""

    def step(self, dt_s: float, force_n: float, reference_n: float) -> float:
        """One update; returns the requested ratio."""
        check_sample(dt_s, force_n, reference_n)
        error = reference_n - force_n
        previous = error if self._error_n is None else self._error_n
        self._error_n = error
        cfg = self.config
        ratio = self.ratio + cfg.kp_per_n * (error - previous) + cfg.ki_per_n_s * dt_s * error
        self.ratio = min(max(ratio, 0.0), cfg.ratio_max)
        return self.ratio
