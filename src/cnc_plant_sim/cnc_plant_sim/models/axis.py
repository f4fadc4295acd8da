"""One feed-drive axis: position(s) = K/(s(τs+1)) · (u − F_d), with stiction.

Inside the model the paper's units hold: position in BLU, velocity in BLU/s,
command ``u`` and friction ``F_d`` in drive (DAC) units, K in BLU/s per DAC
unit. The public API is SI (m, m/s); ``blu_m`` converts at the edge. The
friction model takes velocity in mm/s.

The state ``x = [pos_blu, vel_blu_s]`` obeys ::

    d pos/dt = vel
    d vel/dt = (K·(u − F(vel)) − vel) / τ

:func:`dynamics` gives this vector field for scipy. :meth:`FeedDriveAxis.step`
integrates it with the command held constant over ``dt_s`` (zero-order hold)
in ``substeps`` equal sub-steps. In each sub-step the friction is linearised at
the sub-step's initial velocity, ``F ≈ F0 + F'·(v − v0)``, and the resulting
linear first-order lag is solved exactly (exponential integrator). With
``F' = 0`` this is ``v(t+h) = v·e^{−h/τ} + K·(u − F0)·(1 − e^{−h/τ})``; for
friction that is affine in v on each branch (none, viscous, Coulomb+viscous
away from reversals) the step is exact. The slope is limited so that the
linearised lag never becomes unstable (``1 + K·F'·mm_per_blu >= 0``).

Stiction: if the velocity would cross zero within a sub-step, the axis stops
at zero at the crossing time; a stopped axis stays stopped while
``breakaway_negative <= u <= breakaway_positive`` (the friction then balances
the command, and ``friction_force`` reports ``u``); otherwise it restarts, for
the rest of the sub-step, on the friction branch of the command's direction.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.config import build_config, require_non_negative, require_positive
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import param
from cnc_contour_control.core.units import M_PER_BLU_PAPER000, M_PER_MM
from cnc_plant_sim.models.friction import FrictionModel, make_friction

#: Below this |a·h| the exponential functions use their Taylor series.
_SERIES_LIMIT = 1.0e-3


@dataclass(frozen=True)
class AxisConfig:
    """Validated parameters of one feed-drive axis.

    Parameters
    ----------
    name : str
        Axis name (``"x"``).
    gain_blu_s_per_dac : float
        Open-loop velocity gain K [BLU/s per DAC unit], > 0.
    time_constant_s : float
        Drive time constant τ [s], > 0.
    friction : str
        Friction model name from :data:`cnc_plant_sim.models.friction.FRICTIONS`.
    friction_params : Mapping
        Params of that model (checked by building it).
    friction_scale : float
        Extra factor on the friction (the plant's random variation), >= 0.
    blu_m : float
        Length of one BLU [m], > 0 (paper 000: 1e-5).
    substeps : int
        Sub-steps per :meth:`FeedDriveAxis.step`, >= 1.
    command_limit_dac : float or None
        Symmetric saturation of the drive input [DAC], > 0; None: no limit.
    """

    name: str = param(read_only=True, description="axis name")
    gain_blu_s_per_dac: float = param(unit="BLU/s per DAC", read_only=True,
                                      description="open-loop velocity gain K, > 0")
    time_constant_s: float = param(unit="s", read_only=True, description="drive time constant tau, > 0")
    friction: str = param("none", read_only=True, description="friction model (a name in FRICTIONS)")
    friction_params: Mapping[str, Any] = param(default_factory=dict, read_only=True,
                                               description="params of the friction model")
    friction_scale: float = param(1.0, read_only=True, description="factor on the friction, >= 0")
    blu_m: float = param(M_PER_BLU_PAPER000, unit="m", read_only=True, description="length of one BLU, > 0")
    substeps: int = param(1, read_only=True, description="integration sub-steps per step, >= 1")
    command_limit_dac: float | None = param(None, unit="DAC", read_only=True,
                                            description="symmetric saturation of the drive input, > 0 (unset: none)")

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"name must be a non-empty string, got {self.name!r}")
        require_positive("gain_blu_s_per_dac", self.gain_blu_s_per_dac)
        require_positive("time_constant_s", self.time_constant_s)
        require_positive("blu_m", self.blu_m)
        require_non_negative("friction_scale", self.friction_scale)
        _require_int_at_least("substeps", self.substeps, 1)
        if self.command_limit_dac is not None:
            require_positive("command_limit_dac", self.command_limit_dac)
        if not isinstance(self.friction_params, Mapping):
            raise ConfigError(f"friction_params must be a mapping, got {self.friction_params!r}")
        object.__setattr__(self, "friction_params", dict(self.friction_params))
        self.make_friction()

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], context: str = "axis") -> AxisConfig:
        """Build from a mapping; unknown keys are an error listing the valid ones."""
        return build_config(cls, mapping, context=context)

    def make_friction(self) -> FrictionModel:
        """The friction model of this axis, ``friction_scale`` applied."""
        return make_friction(self.friction, self.friction_params).scaled(self.friction_scale)


def _require_int_at_least(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ConfigError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class DriveParams:
    """The parameters :func:`dynamics` needs (built by :class:`FeedDriveAxis`).

    Attributes
    ----------
    gain_blu_s_per_dac : float
        K [BLU/s per DAC unit].
    time_constant_s : float
        τ [s].
    friction : FrictionModel
        Friction, velocity in mm/s, force in DAC units.
    blu_m : float
        Length of one BLU [m].
    command_limit_dac : float
        Symmetric saturation of u [DAC] (``inf``: none).
    """

    gain_blu_s_per_dac: float
    time_constant_s: float
    friction: FrictionModel
    blu_m: float
    command_limit_dac: float = math.inf


def _clip(u: float, limit: float) -> float:
    return -limit if u < -limit else (limit if u > limit else u)


def _static_net(u: float, friction: FrictionModel) -> float:
    """Net drive force [DAC] on an axis at rest: zero while u lies between the breakaway levels."""
    high, low = friction.breakaway_positive, friction.breakaway_negative
    if u > high:
        return u - high
    if u < low:
        return u - low
    return 0.0


def dynamics(t: float, x: npt.ArrayLike, u: float, params: DriveParams) -> npt.NDArray[np.float64]:
    """State derivative of the axis (for ``scipy.integrate.solve_ivp``).

    Parameters
    ----------
    t : float
        Time [s] (unused: the axis is time-invariant).
    x : array_like, shape (2,)
        ``[pos_blu, vel_blu_s]``.
    u : float
        Command [DAC units].
    params : DriveParams
        Axis parameters.

    Returns
    -------
    ndarray, shape (2,)
        ``[vel_blu_s, acc_blu_s2]``. At exactly zero velocity the static
        friction holds the axis while the command lies between the breakaway
        levels.
    """
    vel = float(np.asarray(x, dtype=float)[1])
    u = _clip(float(u), params.command_limit_dac)
    if vel == 0.0:
        net = _static_net(u, params.friction)
    else:
        net = u - params.friction.force(vel * params.blu_m / M_PER_MM)
    acc = (params.gain_blu_s_per_dac * net - vel) / params.time_constant_s
    return np.array([vel, acc])


def _phi(a: float, h: float) -> tuple[float, float]:
    """``phi1 = (1 − e^{−ah})/a`` and ``phi2 = (h − phi1)/a``, stable near ``a = 0``."""
    x = a * h
    if abs(x) < _SERIES_LIMIT:
        phi1 = h * (1.0 - x / 2.0 + x * x / 6.0 - x * x * x / 24.0)
        phi2 = h * h * (0.5 - x / 6.0 + x * x / 24.0 - x * x * x / 120.0)
        return phi1, phi2
    phi1 = -math.expm1(-x) / a
    return phi1, (h - phi1) / a


def _stop_time(v0: float, d0: float, a: float, h: float) -> float:
    """Time in [0, h] at which ``v0 + d0·phi1(t)`` reaches zero."""
    ratio = -v0 / d0
    if a > 0.0:
        arg = -a * ratio
        t = -math.log1p(arg) / a if arg > -1.0 else h
    else:
        t = ratio
    return min(max(t, 0.0), h)


class FeedDriveAxis:
    """A feed-drive axis K/(s(τs+1)) on (u − F_d) with friction and stiction.

    Parameters
    ----------
    config : AxisConfig
        Validated axis parameters.
    """

    def __init__(self, config: AxisConfig) -> None:
        self.config = config
        self.name = config.name
        self.friction = config.make_friction()
        limit = math.inf if config.command_limit_dac is None else float(config.command_limit_dac)
        self.params = DriveParams(float(config.gain_blu_s_per_dac), float(config.time_constant_s),
                                  self.friction, float(config.blu_m), limit)
        self._k = self.params.gain_blu_s_per_dac
        self._tau = self.params.time_constant_s
        self._blu_m = self.params.blu_m
        self._mm_per_blu = self.params.blu_m / M_PER_MM
        self._linearise = self.friction.linearise
        self._limit = limit
        self._substeps = int(config.substeps)
        self._break_pos = self.friction.breakaway_positive
        self._break_neg = self.friction.breakaway_negative
        self.reset()

    def reset(self, position_m: float = 0.0, velocity_m_s: float = 0.0) -> None:
        """Set the state [m, m/s]; the friction force reads 0 until the next step."""
        for name, value in (("position_m", position_m), ("velocity_m_s", velocity_m_s)):
            if not math.isfinite(value):
                raise FaultError(f"axis {self.name}: reset {name} must be finite, got {value!r}")
        self._pos_blu = float(position_m) / self.params.blu_m
        self._vel_blu_s = float(velocity_m_s) / self.params.blu_m
        self._friction_force = 0.0

    # ----------------------------------------------------------------- state
    @property
    def position_m(self) -> float:
        """Position [m]."""
        return self._pos_blu * self._blu_m

    @property
    def velocity_m_s(self) -> float:
        """Velocity [m/s]."""
        return self._vel_blu_s * self._blu_m

    def state_m(self) -> tuple[float, float]:
        """(position [m], velocity [m/s]): both properties in one call (the plant's per-tick read)."""
        blu_m = self._blu_m
        return self._pos_blu * blu_m, self._vel_blu_s * blu_m

    @property
    def position_blu(self) -> float:
        """Position [BLU]."""
        return self._pos_blu

    @property
    def velocity_blu_s(self) -> float:
        """Velocity [BLU/s]."""
        return self._vel_blu_s

    @property
    def friction_force(self) -> float:
        """Friction force [DAC units] applied in the last sub-step (equals u while stuck)."""
        return self._friction_force

    @property
    def stopped(self) -> bool:
        """True when the axis is at rest (velocity exactly zero)."""
        return self._vel_blu_s == 0.0

    # ----------------------------------------------------------------- stepping
    def step(self, command: float, dt_s: float) -> None:
        """Hold ``command`` [DAC units] for ``dt_s`` [s] and integrate.

        Raises
        ------
        FaultError
            If the command or ``dt_s`` is not finite, ``dt_s <= 0``, or the
            state would become non-finite; the state is left unchanged.
        """
        u = command if type(command) is float else self._as_float(command)
        if u - u != 0.0:  # a NaN or an infinity
            raise FaultError(f"axis {self.name}: command must be finite, got {command!r}")
        if not (dt_s > 0.0 and dt_s < math.inf):  # also refuses NaN
            raise FaultError(f"axis {self.name}: dt_s must be finite and > 0, got {dt_s!r}")
        self.advance(u, dt_s)

    def advance(self, u: float, dt_s: float) -> None:
        """:meth:`step` for a command and a period already checked (finite float, ``dt_s`` > 0).

        The plant checks every axis's command before any axis moves, then
        advances each through here; the checks are not made twice.
        """
        limit = self._limit
        u = -limit if u < -limit else (limit if u > limit else u)
        if self._substeps == 1:
            p, v, f = self._substep(self._pos_blu, self._vel_blu_s, u, dt_s)
        else:
            p, v, f = self._substeps_of(u, dt_s / self._substeps)
        if p - p != 0.0 or v - v != 0.0:  # a NaN or an infinity
            raise FaultError(f"axis {self.name}: state became non-finite (pos {p}, vel {v})")
        self._pos_blu, self._vel_blu_s, self._friction_force = p, v, f

    def _substeps_of(self, u: float, h: float) -> tuple[float, float, float]:
        """All sub-steps of one step, ``h`` seconds each; returns (p, v, friction_dac)."""
        p, v, f = self._pos_blu, self._vel_blu_s, self._friction_force
        for _ in range(self._substeps):
            p, v, f = self._substep(p, v, u, h)
        return p, v, f

    def _as_float(self, command: float) -> float:
        try:
            return float(command)
        except (TypeError, ValueError) as err:
            raise FaultError(f"axis {self.name}: command must be a number, got {command!r}") from err

    def _substep(self, p: float, v: float, u: float, h: float) -> tuple[float, float, float]:
        """Advance (pos_blu, vel_blu_s) by ``h`` seconds; returns (p, v, friction_dac)."""
        if v == 0.0:
            if self._break_neg <= u <= self._break_pos:
                return p, 0.0, u
            direction = 1 if u > self._break_pos else -1
        else:
            direction = 1 if v > 0.0 else -1
        mm_per_blu, k, tau = self._mm_per_blu, self._k, self._tau
        f0, slope = self._linearise(v * mm_per_blu, direction)
        a = 1.0 + k * slope * mm_per_blu
        a = (a if a > 0.0 else 0.0) / tau
        d0 = (k * (u - f0) - v) / tau
        phi1, phi2 = _phi(a, h)
        v1 = v + d0 * phi1
        if v != 0.0 and v1 * direction < 0.0:
            t_stop = _stop_time(v, d0, a, h)
            p_stop = p + v * t_stop + d0 * _phi(a, t_stop)[1]
            if t_stop < h:
                return self._substep(p_stop, 0.0, u, h - t_stop)
            return p_stop, 0.0, f0
        return p + v * h + d0 * phi2, v1, f0
