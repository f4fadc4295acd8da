"""A mechanistic milling process: the 2-axis feed speed in, the resultant cutting force out (ROS-free).

The linear edge-force model (Altintas, *Manufacturing Automation*, ch. 2). Tooth j
of ``z`` at immersion φ_j (from the normal to the feed, in the cut while
φ_st <= φ_j <= φ_ex) cuts a chip of thickness h = c sin φ_j, with the feed
per tooth c = v_feed / (N z) [mm]::

    F_t = a_p (K_tc h + K_te)      tangential [N]     (a_p axial depth [mm], K_tc [N/mm²], K_te [N/mm])
    F_r = a_p (K_rc h + K_re)      radial [N]
    F_f = −F_t cos φ − F_r sin φ   along the feed, summed over the teeth in the cut
    F_n =  F_t sin φ − F_r cos φ   normal to the feed

The mean over one tooth pass is closed-form and linear in c and a_p,
``F̄ = a_p (c A_c + A_e)`` (``A_c``, ``A_e``: 2-vectors of the geometry and the
coefficients, :func:`mean_force_vectors`). The tooth-passing part
``F(φ(t)) − F̄`` is periodic at f_d = N z / 60 with zero mean: paper 002's
cutting disturbance, here from the same geometry instead of an assumed
sinusoid. One sample of ``dt_s`` with the feed speed held::

    c   = |v_feed| · 60000 / (N z)                   feed per tooth [mm] (v_feed in m/s)
    F̄   ← lag_pass(a_p(t) (c A_c + A_e))             the mean per tooth pass, τ = 60 (1 − e⁻¹)/(N z)
    F   = |F̄ + g (F(φ(t)) − F̄_now)|                  resultant in the feed plane [N]; g = periodic_gain
    F_m ← lag_dyn(F) + noise                         the dynamometer (τ_dyn = 0: none), seeded noise

The three middle lines run on sub-steps of ``dt_s`` (at least ``substeps_per_tooth``
per tooth period), so a dynamometer lag filters the tooth-passing force
instead of a sample of it held for ``dt_s`` (which would alias).

The pass lag plays the part of turning's chip lag τ_c (Eq. 4 of paper 004,
one revolution there, one tooth pass here). The axial depth a_p(t) is the
``plant.cutting`` depth schedule; the radial depth a_e sets the immersion
(``up``: φ_st = 0, φ_ex = acos(1 − 2 a_e/D); ``down``: φ_st = π − acos(1 − 2 a_e/D),
φ_ex = π). The spindle angle is 2π N t/60 (the spindle speed is constant).
The regulated force is the resultant |F| (the ``cutting_force`` wrench's ``force.x``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.config import require_choice, require_finite, require_non_negative, require_positive
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.force_model import CHIP_TIME_FACTOR, DepthSchedule, FirstOrderLag
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.core.units import MM_MIN_PER_M_S
from cnc_contour_control.disturbance.design import disturbance_frequency_hz

#: Immersion angles (φ_st, φ_ex) [rad] of each milling direction, from a_e/D.
IMMERSIONS = {
    "up": lambda ratio: (0.0, math.acos(1.0 - 2.0 * ratio)),
    "down": lambda ratio: (math.pi - math.acos(1.0 - 2.0 * ratio), math.pi),
}


@dataclass(frozen=True)
class MillingConfig:
    """Validated description of the milling process (axial depth: the ``plant.cutting`` depth schedule).

    Parameters
    ----------
    tangential_n_mm2, radial_n_mm2 : float
        Cutting coefficients K_tc, K_rc [N/mm²], in [0, 1e5] (defaults: Al 7050, Altintas).
    tangential_edge_n_mm, radial_edge_n_mm : float
        Edge coefficients K_te, K_re [N/mm], in [0, 1e4].
    tool_diameter_mm : float
        D [mm], in [0.1, 1000].
    flutes : int
        z, in [1, 100].
    spindle_rpm : float
        N [rev/min], in [1, 1e6].
    radial_engagement : float
        a_e / D, the radial depth as a share of the diameter, in (0, 1] (a ratio, so no
        bound depends on another field; ``radial_depth_mm`` gives a_e).
    immersion : str
        ``down`` (climb) or ``up`` (conventional).
    periodic_gain : float
        g, the share of the tooth-passing part in the force, in [0, 1] (0: the mean per pass only).
    feed_axes : tuple of str
        The plant axes whose velocities make the feed (their vector's magnitude counts), 1 to 3 names.
    substeps_per_tooth : int
        The process is stepped at least this often per tooth period inside one ``step`` [1, 1000].
    noise_n : float
        Standard deviation of the measurement noise [N], in [0, 1e4].
    dynamometer_tau_s : float
        Time constant of the dynamometer [s], in [0, 10] (0: none).
    seed : int
        Seed of the noise, >= 0.
    """

    tangential_n_mm2: float = param(796.0, unit="N/mm^2", low=0.0, high=1.0e5, description="cutting coefficient K_tc")
    radial_n_mm2: float = param(168.0, unit="N/mm^2", low=0.0, high=1.0e5, description="cutting coefficient K_rc")
    tangential_edge_n_mm: float = param(27.7, unit="N/mm", low=0.0, high=1.0e4, description="edge coefficient K_te")
    radial_edge_n_mm: float = param(30.8, unit="N/mm", low=0.0, high=1.0e4, description="edge coefficient K_re")
    tool_diameter_mm: float = param(10.0, unit="mm", low=0.1, high=1000.0, description="tool diameter D")
    flutes: int = param(2, low=1, high=100, description="flutes z")
    spindle_rpm: float = param(1200.0, unit="rev/min", low=1.0, high=1.0e6, description="spindle speed N")
    radial_engagement: float = param(0.5, low=1.0e-6, high=1.0, description="radial depth as a share of D, a_e/D")
    immersion: str = param("down", description="milling direction (down, up)")
    periodic_gain: float = param(1.0, low=0.0, high=1.0, description="share of the tooth-passing force")
    feed_axes: tuple[str, ...] = param(("x", "y"), description="plant axes whose velocity vector is the feed")
    substeps_per_tooth: int = param(8, low=1, high=1000, description="sub-steps per tooth period (at least)")
    noise_n: float = param(0.0, unit="N", low=0.0, high=1.0e4, description="measurement noise (std)")
    dynamometer_tau_s: float = param(0.0, unit="s", low=0.0, high=10.0, description="dynamometer lag")
    seed: int = param(0, low=0, high=2**31 - 1, description="seed of the measurement noise")

    def __post_init__(self) -> None:
        check_ranges(self, "milling")
        require_choice("milling.immersion", self.immersion, IMMERSIONS)
        axes = self.feed_axes
        if isinstance(axes, (str, bytes)) or not 1 <= len(axes) <= 3 or not all(
                isinstance(a, str) and a for a in axes) or len(set(axes)) != len(axes):
            raise ConfigError(f"milling.feed_axes must be 1 to 3 distinct axis names, got {axes!r}")
        object.__setattr__(self, "feed_axes", tuple(axes))

    @property
    def immersion_rad(self) -> tuple[float, float]:
        """(φ_st, φ_ex) [rad]."""
        return IMMERSIONS[self.immersion](self.radial_engagement)

    @property
    def radial_depth_mm(self) -> float:
        """a_e [mm]."""
        return self.radial_engagement * self.tool_diameter_mm

    @property
    def tooth_frequency_hz(self) -> float:
        """f_d = N z / 60 [Hz]."""
        return disturbance_frequency_hz(self.spindle_rpm, self.flutes)

    @property
    def pass_tau_s(self) -> float:
        """τ of the mean per tooth pass [s]: 60 (1 − e⁻¹)/(N z)."""
        return CHIP_TIME_FACTOR / (self.spindle_rpm * self.flutes)

    def feed_per_tooth_mm(self, feed_speed_m_s: float) -> float:
        """c [mm] of the feed speed [m/s]."""
        return abs(feed_speed_m_s) * MM_MIN_PER_M_S / (self.spindle_rpm * self.flutes)


def _antiderivatives(config: MillingConfig, phi: float) -> npt.NDArray[np.float64]:
    """∫ (F_f, F_n) dφ per unit a_p at ``phi``: row 0 the part per mm of c, row 1 the edge part (shape (2, 2))."""
    ktc, krc, kte, kre = (config.tangential_n_mm2, config.radial_n_mm2, config.tangential_edge_n_mm,
                          config.radial_edge_n_mm)
    sin2_half = 0.5 * math.sin(phi) ** 2                        # ∫ sin φ cos φ
    sq = 0.5 * phi - 0.25 * math.sin(2.0 * phi)                 # ∫ sin² φ
    per_chip = (-(ktc * sin2_half + krc * sq), ktc * sq - krc * sin2_half)
    edge = (-(kte * math.sin(phi) - kre * math.cos(phi)), -kte * math.cos(phi) - kre * math.sin(phi))
    return np.array([per_chip, edge])


def mean_force_vectors(config: MillingConfig) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(A_c [N/mm²], A_e [N/mm]), shape (2,) each: the mean (F_f, F_n) per tooth pass is a_p (c A_c + A_e) [N]."""
    start, end = config.immersion_rad
    rows = config.flutes / (2.0 * math.pi) * (_antiderivatives(config, end) - _antiderivatives(config, start))
    return rows[0], rows[1]


def instant_force(config: MillingConfig, spindle_rad: float, feed_per_tooth_mm: float,
                  depth_mm: float) -> npt.NDArray[np.float64]:
    """(F_f, F_n) [N] summed over the teeth in the cut at spindle angle ``spindle_rad`` (module docstring)."""
    start, end = config.immersion_rad
    total = np.zeros(2)
    for j in range(config.flutes):
        phi = (spindle_rad + 2.0 * math.pi * j / config.flutes) % (2.0 * math.pi)
        if start <= phi <= end:
            chip = feed_per_tooth_mm * math.sin(phi)
            f_t = depth_mm * (config.tangential_n_mm2 * chip + config.tangential_edge_n_mm)
            f_r = depth_mm * (config.radial_n_mm2 * chip + config.radial_edge_n_mm)
            total += (-f_t * math.cos(phi) - f_r * math.sin(phi), f_t * math.sin(phi) - f_r * math.cos(phi))
    return total


class MillingProcess:
    """The milling process (module docstring); time is the sum of the ``dt_s`` given to :meth:`step`.

    Parameters
    ----------
    config : MillingConfig
        Coefficients, tool, spindle, immersion.
    schedule : DepthSchedule
        Axial depth a_p [mm] against time.
    """

    def __init__(self, config: MillingConfig, schedule: DepthSchedule) -> None:
        self.config, self.schedule = config, schedule
        self.per_chip, self.edge = mean_force_vectors(config)
        self._pass = [FirstOrderLag(config.pass_tau_s), FirstOrderLag(config.pass_tau_s)]
        self._dynamometer = FirstOrderLag(config.dynamometer_tau_s)
        self._omega_rad_s = 2.0 * math.pi * config.spindle_rpm / 60.0
        self.reset()

    def reset(self) -> None:
        """Time 0, no force, the schedule in force, the noise reseeded."""
        self.t_s, self.force_n, self.measured_n = 0.0, 0.0, 0.0
        self._held_depth_mm: float | None = None
        for lag in (*self._pass, self._dynamometer):
            lag.reset(0.0)
        self._rng = np.random.default_rng(self.config.seed)

    def set_depth_mm(self, depth_mm: float | None) -> None:
        """Hold the axial depth ``depth_mm`` [mm] (>= 0) from now on; None returns to the schedule."""
        self._held_depth_mm = None if depth_mm is None else require_non_negative("depth_mm", depth_mm)

    def depth_mm(self) -> float:
        """The axial depth a_p [mm] now."""
        return self.schedule.depth_mm(self.t_s) if self._held_depth_mm is None else self._held_depth_mm

    def mean_force(self, feed_per_tooth_mm: float, depth_mm: float) -> npt.NDArray[np.float64]:
        """The steady mean (F_f, F_n) [N] per tooth pass at feed per tooth c [mm] and axial depth a_p [mm]."""
        return depth_mm * (feed_per_tooth_mm * self.per_chip + self.edge)

    def step(self, feed_speed_m_s: float, dt_s: float) -> float:
        """Hold the feed speed [m/s] for ``dt_s`` [s]; return the measured resultant force [N].

        The sample is cut into ``ceil(substeps_per_tooth · f_d · dt_s)`` equal sub-steps, so the
        tooth-passing force reaches the dynamometer resolved, not sampled once per ``dt_s`` (aliased).
        """
        if not math.isfinite(feed_speed_m_s):
            raise FaultError(f"feed_speed_m_s must be finite, got {feed_speed_m_s!r}")
        require_positive("dt_s", dt_s)
        chip_mm, depth = self.config.feed_per_tooth_mm(feed_speed_m_s), self.depth_mm()
        drive = self.mean_force(chip_mm, depth) if chip_mm > 0.0 else np.zeros(2)
        count = max(1, math.ceil(self.config.substeps_per_tooth * self.config.tooth_frequency_hz * dt_s - 1e-9))
        sub_s, start_s = dt_s / count, self.t_s
        for k in range(1, count + 1):
            self._substep(sub_s, start_s + k * sub_s, drive, chip_mm, depth)
        self.t_s = start_s + dt_s
        noise = self._rng.normal(0.0, self.config.noise_n) if self.config.noise_n > 0.0 else 0.0
        self.measured_n = self._dynamometer.value + noise
        return require_finite("milling force", self.measured_n)

    def _substep(self, sub_s: float, t_s: float, drive: npt.NDArray[np.float64], chip_mm: float,
                 depth_mm: float) -> None:
        """Advance the pass lag, the resultant and the dynamometer by ``sub_s`` [s] to time ``t_s`` [s]."""
        mean = np.array([lag.step(sub_s, float(u)) for lag, u in zip(self._pass, drive)])
        periodic = np.zeros(2)
        if chip_mm > 0.0 and self.config.periodic_gain > 0.0:
            periodic = instant_force(self.config, self._omega_rad_s * t_s, chip_mm, depth_mm) - drive
        self.force_n = float(np.hypot(*(mean + self.config.periodic_gain * periodic)))
        self._dynamometer.step(sub_s, self.force_n)

    def describe(self) -> dict[str, Any]:
        """The process as built (plain types, for the run record)."""
        cfg = self.config
        start, end = cfg.immersion_rad
        return {"model": "milling", "tangential_n_mm2": cfg.tangential_n_mm2, "radial_n_mm2": cfg.radial_n_mm2,
                "tangential_edge_n_mm": cfg.tangential_edge_n_mm, "radial_edge_n_mm": cfg.radial_edge_n_mm,
                "tool_diameter_mm": cfg.tool_diameter_mm, "flutes": cfg.flutes, "spindle_rpm": cfg.spindle_rpm,
                "radial_engagement": cfg.radial_engagement,
                "radial_depth_mm": cfg.radial_depth_mm, "immersion": cfg.immersion,
                "immersion_deg": [math.degrees(start), math.degrees(end)], "periodic_gain": cfg.periodic_gain,
                "tooth_frequency_hz": cfg.tooth_frequency_hz, "feed_axes": list(cfg.feed_axes),
                "depth_schedule": self.schedule.as_lists(), "noise_n": cfg.noise_n,
                "dynamometer_tau_s": cfg.dynamometer_tau_s, "substeps_per_tooth": cfg.substeps_per_tooth,
                "seed": cfg.seed}
