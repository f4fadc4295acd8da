"""The cutting process of a lathe (paper 004, Eqs. 2-4): feed-axis velocity in, cutting force out.

One sample of ``dt_s`` with the feed-axis velocity held::

    v_a   = |v_feed| · 60000 / N            feed per revolution [mm/rev] (v_feed in m/s, N in rpm)
    F_c   ← lag_c(K_s · d(t) · v_a)         τ_c = 60 (1 − e⁻¹)/N, exact under the hold
    F_m   ← lag_dyn(F_c) + noise            the dynamometer: its lag (τ_dyn = 0: none) and seeded Gaussian noise

The depth d(t) comes from a :class:`~cnc_contour_control.core.force_model.DepthSchedule`
(``[[t_s, depth_mm], ...]``, the paper's 1 -> 2 -> 3 mm every 4 s by default)
unless :meth:`TurningProcess.set_depth_mm` holds another value on line. The
interpolator's lag τ_s (Eq. 1) is not here: it belongs to whatever drives the
feed axis. The lags are :class:`~cnc_contour_control.core.force_model.FirstOrderLag`,
the same code the regulators' models step.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cnc_contour_control.core.config import require_finite, require_non_negative, require_positive
from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.core.force_model import CHIP_TIME_FACTOR, DepthSchedule, FirstOrderLag
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.core.units import MM_MIN_PER_M_S

#: The paper's depth schedule: 1 -> 2 -> 3 mm every 4 s.
PAPER004_DEPTHS: tuple[tuple[float, float], ...] = ((0.0, 1.0), (4.0, 2.0), (8.0, 3.0))


@dataclass(frozen=True)
class TurningConfig:
    """Validated description of the cutting process.

    Parameters
    ----------
    specific_force_n_mm2, spindle_rpm : float
        K_s and N of the real process, as :class:`~cnc_contour_control.core.force_model.TurningModelConfig`
        states them for the regulator's nominal model (which may differ from these).
    depth_schedule : sequence of (t_s, depth_mm)
        Depth of cut against time; times strictly increasing, depths >= 0.
    noise_n : float
        Standard deviation of the measurement noise [N], in [0, 1e4].
    dynamometer_tau_s : float
        Time constant of the dynamometer [s], in [0, 10] (0: none).
    seed : int
        Seed of the noise (``numpy.random.default_rng``), >= 0.
    """

    specific_force_n_mm2: float = param(1773.0, unit="N/mm^2", low=1.0, high=1.0e5,
                                        description="specific cutting force K_s")
    spindle_rpm: float = param(600.0, unit="rev/min", low=1.0, high=1.0e5, description="spindle speed N")
    depth_schedule: tuple[tuple[float, float], ...] = param(PAPER004_DEPTHS,
                                                             description="depth of cut [[t_s, depth_mm], ...]")
    noise_n: float = param(0.0, unit="N", low=0.0, high=1.0e4, description="measurement noise (std)")
    dynamometer_tau_s: float = param(0.0, unit="s", low=0.0, high=10.0, description="dynamometer lag")
    seed: int = param(0, low=0, high=2**31 - 1, description="seed of the measurement noise", read_only=True)

    def __post_init__(self) -> None:
        check_ranges(self, "turning")
        schedule = DepthSchedule(self.depth_schedule)
        object.__setattr__(self, "depth_schedule", tuple(schedule.points))

    @property
    def chip_tau_s(self) -> float:
        """τ_c = 60 (1 − e⁻¹)/N [s] (Eq. 4)."""
        return CHIP_TIME_FACTOR / self.spindle_rpm


class TurningProcess:
    """The cutting process (module docstring); time is the sum of the ``dt_s`` given to :meth:`step`."""

    def __init__(self, config: TurningConfig) -> None:
        self.config = config
        self.schedule = DepthSchedule(config.depth_schedule)
        self._chip = FirstOrderLag(config.chip_tau_s)
        self._dynamometer = FirstOrderLag(config.dynamometer_tau_s)
        self.reset()

    def reset(self, force_n: float = 0.0) -> None:
        """Time 0, steady at ``force_n`` [N], the schedule in force, the noise reseeded."""
        self.t_s = 0.0
        self._held_depth_mm: float | None = None
        self._chip.reset(require_finite("force_n", force_n))
        self._dynamometer.reset(force_n)
        self._rng = np.random.default_rng(self.config.seed)
        self.measured_n = force_n

    def set_depth_mm(self, depth_mm: float | None) -> None:
        """Hold ``depth_mm`` [mm] (>= 0) from now on instead of the schedule; None returns to the schedule."""
        self._held_depth_mm = None if depth_mm is None else require_non_negative("depth_mm", depth_mm)

    def depth_mm(self) -> float:
        """The depth of cut [mm] now."""
        return self.schedule.depth_mm(self.t_s) if self._held_depth_mm is None else self._held_depth_mm

    def feed_mm_rev(self, feed_velocity_m_s: float) -> float:
        """Feed per revolution [mm/rev] of the feed-axis velocity [m/s] (Eq. 2)."""
        return abs(feed_velocity_m_s) * MM_MIN_PER_M_S / self.config.spindle_rpm

    @property
    def force_n(self) -> float:
        """The true cutting force F_c [N] (before the dynamometer)."""
        return self._chip.value

    def step(self, feed_velocity_m_s: float, dt_s: float) -> float:
        """Hold the feed velocity [m/s] for ``dt_s`` [s]; return the measured force [N]."""
        if not math.isfinite(feed_velocity_m_s):
            raise FaultError(f"feed_velocity_m_s must be finite, got {feed_velocity_m_s!r}")
        require_positive("dt_s", dt_s)
        drive = self.config.specific_force_n_mm2 * self.depth_mm() * self.feed_mm_rev(feed_velocity_m_s)
        self.t_s += dt_s
        force = self._dynamometer.step(dt_s, self._chip.step(dt_s, drive))
        noise = self._rng.normal(0.0, self.config.noise_n) if self.config.noise_n > 0.0 else 0.0
        self.measured_n = force + noise
        return self.measured_n

    def describe(self) -> dict[str, Any]:
        """The process as built (plain types, for the run record)."""
        cfg = self.config
        return {"model": "turning", "specific_force_n_mm2": cfg.specific_force_n_mm2, "spindle_rpm": cfg.spindle_rpm,
                "chip_tau_s": cfg.chip_tau_s, "depth_schedule": self.schedule.as_lists(), "noise_n": cfg.noise_n,
                "dynamometer_tau_s": cfg.dynamometer_tau_s, "seed": cfg.seed}

