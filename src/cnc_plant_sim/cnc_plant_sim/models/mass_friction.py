"""Paper 001's axes: a mass driven by a force against viscous, Coulomb and Stribeck friction (Eqs. 18-19).

Per axis, in the model's own length unit L (``length_unit``: what c and ċ carry
in the paper's equations; the paper states no units)::

    m c̈ = u − F_f(ċ) − F_cut                                          (18)
    F_f = B ċ + f_c sgn(ċ) + f_s e^(−α|ċ|) sgn(ċ)                     (19)

u and the forces in N, m [N s²/L], B [N s/L], α [s/L]. Table 1: X m 0.45,
B 0.01, f_c 3, f_s 1, α 2; Y m 0.65, B 0.01, f_c 4, f_s 1.5, α 2 (the printed
Eq. 19 has ``e^(−α ċ)``; we read ``|ċ|`` so the friction is odd in ċ). A Z
axis, if asked for, copies Y (our choice; the paper has two axes).
``axis_overrides`` may change any key of :class:`MassFrictionAxisConfig`.
The interface is SI (m, m/s): positions are converted at the model's edge,
the topics never see L. The command is a force in N in every reading.

Stiction: an axis at rest stays at rest while ``|u − F_cut| <= f_c + f_s``
(the breakaway level; the friction then balances the net command). A moving
axis whose velocity would cross zero within a sub-step stops at the crossing
and the stiction rule decides the rest of the sub-step, so the velocity never
chatters through zero.

Integration (:func:`substep`): the command is held over ``dt_s`` (zero-order
hold), split into ``substeps`` equal sub-steps. In each the friction is
linearised at the sub-step's initial velocity on the branch of the motion,
``F ≈ F0 + F'·(ċ − ċ0)``, and the resulting linear ODE is solved exactly
(exponential integrator; F' may be negative on the Stribeck curve). This is
exact for affine friction (B, f_c); the Stribeck term's error is second order
in the velocity change of a sub-step (``test_mass_friction`` checks it against
``scipy.integrate.solve_ivp``).

Cutting load (Fig. 8: "a nonlinear cutting force not seen in training, added to
both axes"; the paper gives no formula). Chosen from :data:`CUTTING_LOADS` by
``cutting_load`` (``none`` by default). ``feed_power``: a force whose size
grows as a power of the path speed, ``|F| = cutting_force_n · (|v| /
cutting_speed_mm_s)^cutting_exponent`` (Kienzle's ``F ∝ h^(1−m_c)`` with chip
thickness h ∝ feed and ``1 − m_c = 0.75``), pushing the tool back along the
feed direction ``t = v/|v|`` and sideways along ``−n``, n = t turned +90° in
the plane of the first two axes (to the right of the feed for
``cutting_normal_ratio`` > 0): the load per axis is ``F_i = |F| · (t_i +
ratio · n_i)``. The sideways part pushes the tool off the contour; the feed part
alone acts like extra damping. The load is evaluated from the SI velocities at
the start of each step and held over the step, like the command.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import check_ranges, config_values, param
from cnc_contour_control.core.units import M_PER_MM, M_PER_UM
from cnc_plant_sim.models.axis import _phi
from cnc_plant_sim.models.step_checks import check_length, check_step, is_finite_number

#: Metres per model length unit: the unit c and ċ carry in Eqs. 18-19.
LENGTH_UNITS: dict[str, float] = {"m": 1.0, "mm": M_PER_MM, "um": M_PER_UM}
#: Range of every Table 1 parameter a config accepts (mass: the low end is > 0).
PARAM_RANGE = (0.0, 1.0e6)
MIN_MASS = 1.0e-6


@dataclass(frozen=True)
class MassFrictionAxisConfig:
    """Table 1's parameters of one axis, in the model's length unit L (forces in N).

    Parameters
    ----------
    name : str
        Axis name.
    mass : float
        m [N s²/L], in [1e-6, 1e6].
    viscous : float
        B [N s/L], in [0, 1e6].
    coulomb_n : float
        f_c [N], in [0, 1e6].
    stribeck_n : float
        f_s [N], the static excess over f_c (breakaway at f_c + f_s), in [0, 1e6].
    stribeck_decay : float
        α [s/L], in [0, 1e6].
    """

    name: str = param(read_only=True, description="axis name")
    mass: float = param(unit="N s^2/L", low=MIN_MASS, high=PARAM_RANGE[1], read_only=True,
                        description="moving mass m (L: mass_friction.length_unit)")
    viscous: float = param(unit="N s/L", low=PARAM_RANGE[0], high=PARAM_RANGE[1], read_only=True,
                           description="viscous friction B")
    coulomb_n: float = param(unit="N", low=PARAM_RANGE[0], high=PARAM_RANGE[1], read_only=True,
                             description="Coulomb friction f_c")
    stribeck_n: float = param(unit="N", low=PARAM_RANGE[0], high=PARAM_RANGE[1], read_only=True,
                              description="static excess f_s over f_c (breakaway at f_c + f_s)")
    stribeck_decay: float = param(unit="s/L", low=PARAM_RANGE[0], high=PARAM_RANGE[1], read_only=True,
                                  description="Stribeck decay alpha of f_s")

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"name must be a non-empty string, got {self.name!r}")
        check_ranges(self)

    @property
    def breakaway_n(self) -> float:
        """Static friction level f_c + f_s [N] a net command must exceed to start the axis."""
        return self.coulomb_n + self.stribeck_n


#: Paper 001, Table 1 (units not stated: read in ``length_unit``); Z copies Y.
PAPER001_AXES: dict[str, dict[str, float]] = {
    "x": {"mass": 0.45, "viscous": 0.01, "coulomb_n": 3.0, "stribeck_n": 1.0, "stribeck_decay": 2.0},
    "y": {"mass": 0.65, "viscous": 0.01, "coulomb_n": 4.0, "stribeck_n": 1.5, "stribeck_decay": 2.0},
    "z": {"mass": 0.65, "viscous": 0.01, "coulomb_n": 4.0, "stribeck_n": 1.5, "stribeck_decay": 2.0},
}


@dataclass(frozen=True)
class MassFrictionOptions:
    """Model-wide options of the mass-friction plant (the ``mass_friction`` section of a plant config).

    Parameters
    ----------
    length_unit : str
        The unit of c and ċ in Eqs. 18-19, one of :data:`LENGTH_UNITS`.
    cutting_load : str
        Cutting load model, one of :data:`CUTTING_LOADS` (``none``: off).
    cutting_force_n : float
        Size of the feed force at ``cutting_speed_mm_s`` [N], in [0, 1e6].
    cutting_speed_mm_s : float
        Path speed where the feed force is ``cutting_force_n`` [mm/s], in [1e-6, 1e6].
    cutting_exponent : float
        Power of the path speed, in [0, 3] (Kienzle: 0.75).
    cutting_normal_ratio : float
        Sideways (cross-feed) part over the feed part, in [-2, 2].
    """

    length_unit: str = param("mm", read_only=True,
                             description=f"unit of c in Eqs. 18-19, one of {sorted(LENGTH_UNITS)}")
    cutting_load: str = param("none", read_only=True, description="cutting load model (none: off)")
    cutting_force_n: float = param(200.0, unit="N", low=0.0, high=1.0e6, read_only=True,
                                   description="feed force at cutting_speed_mm_s")
    cutting_speed_mm_s: float = param(5000.0 / 60.0, unit="mm/s", low=1.0e-6, high=1.0e6, read_only=True,
                                      description="path speed where the feed force is cutting_force_n")
    cutting_exponent: float = param(0.75, low=0.0, high=3.0, read_only=True,
                                    description="power of the path speed in the feed force")
    cutting_normal_ratio: float = param(0.5, low=-2.0, high=2.0, read_only=True,
                                        description="cross-feed force over feed force (> 0: pushes to the right)")

    def __post_init__(self) -> None:
        require_choice("length_unit", self.length_unit, LENGTH_UNITS, "mass_friction")
        require_choice("cutting_load", self.cutting_load, CUTTING_LOADS, "mass_friction")
        check_ranges(self, "mass_friction")

    @property
    def m_per_unit(self) -> float:
        """Metres per model length unit."""
        return LENGTH_UNITS[self.length_unit]


# --------------------------------------------------------------------------- cutting loads

#: A cutting load: (axis velocities [m/s], options) -> force per axis [N], against the motion when positive.
CuttingLoad = Callable[[Sequence[float], MassFrictionOptions], list[float]]


def no_load(velocities_m_s: Sequence[float], options: MassFrictionOptions) -> list[float]:
    """No cutting force."""
    return [0.0] * len(velocities_m_s)


def feed_power_load(velocities_m_s: Sequence[float], options: MassFrictionOptions) -> list[float]:
    """``|F| = cutting_force_n · (|v|/v_ref)^p`` along the feed plus ``ratio`` times it across, per axis [N]."""
    speed_m_s = math.hypot(*velocities_m_s)
    if speed_m_s == 0.0:
        return [0.0] * len(velocities_m_s)
    ratio = speed_m_s / (options.cutting_speed_mm_s * M_PER_MM)
    size_n = options.cutting_force_n * ratio ** options.cutting_exponent / speed_m_s
    forces = [size_n * v for v in velocities_m_s]
    if len(forces) >= 2:  # the cross-feed part: n = t turned +90° in the plane of the first two axes
        across = options.cutting_normal_ratio * size_n
        forces[0] -= across * velocities_m_s[1]
        forces[1] += across * velocities_m_s[0]
    return forces


#: Cutting loads by name.
CUTTING_LOADS: dict[str, CuttingLoad] = {"none": no_load, "feed_power": feed_power_load}


# --------------------------------------------------------------------------- one axis


class AxisParams(NamedTuple):
    """What :func:`substep` and :func:`dynamics` need, model units (L, N, s)."""

    mass: float
    viscous: float
    coulomb_n: float
    stribeck_n: float
    stribeck_decay: float
    breakaway_n: float


def axis_params(config: MassFrictionAxisConfig) -> AxisParams:
    """The plain tuple of one axis's parameters."""
    return AxisParams(config.mass, config.viscous, config.coulomb_n, config.stribeck_n, config.stribeck_decay,
                      config.breakaway_n)


def friction_n(velocity: float, prm: AxisParams) -> float:
    """Kinetic friction F_f of Eq. 19 [N] at ``velocity`` [L/s] (0 at rest: the static force is the net command)."""
    if velocity == 0.0:
        return 0.0
    sign = 1.0 if velocity > 0.0 else -1.0
    stribeck = prm.stribeck_n * math.exp(-prm.stribeck_decay * abs(velocity))
    return prm.viscous * velocity + sign * (prm.coulomb_n + stribeck)


def dynamics(t: float, x: npt.ArrayLike, u: float, prm: AxisParams) -> npt.NDArray[np.float64]:
    """State derivative ``[ċ, c̈]`` of Eq. 18 for ``scipy.integrate.solve_ivp``.

    Parameters
    ----------
    t : float
        Time [s] (unused: time-invariant).
    x : array_like, shape (2,)
        ``[c, ċ]`` [L, L/s].
    u : float
        Net command ``u − F_cut`` [N].
    prm : AxisParams
        Table 1 of the axis.

    Returns
    -------
    ndarray, shape (2,)
        At exactly zero velocity the axis stays while ``|u| <= f_c + f_s``.
    """
    velocity = float(np.asarray(x, dtype=float)[1])
    if velocity == 0.0:
        excess = abs(u) - prm.breakaway_n
        return np.array([0.0, math.copysign(excess, u) / prm.mass if excess > 0.0 else 0.0])
    return np.array([velocity, (u - friction_n(velocity, prm)) / prm.mass])


def _stop_time(v0: float, d0: float, a: float, h: float) -> float:
    """Time in [0, h] at which ``v0 + d0·phi1(a, t)`` reaches zero (``a`` of either sign)."""
    ratio = -v0 / d0
    if abs(a * h) < 1.0e-9:
        t = ratio
    else:
        arg = -a * ratio
        t = -math.log1p(arg) / a if arg > -1.0 else h
    return min(max(t, 0.0), h)


def friction_after(velocity: float, u: float, prm: AxisParams) -> float:
    """The friction [N] of an axis at ``velocity`` [L/s] under the net command ``u`` [N]: at rest, what balances u."""
    if velocity != 0.0:
        return friction_n(velocity, prm)
    return max(-prm.breakaway_n, min(prm.breakaway_n, u))


def substep(p: float, v: float, u: float, h: float, prm: AxisParams) -> tuple[float, float]:
    """Advance ``(c [L], ċ [L/s])`` by ``h`` [s] under the net command ``u`` [N]; returns the new ``(c, ċ)``."""
    if v == 0.0:
        if -prm.breakaway_n <= u <= prm.breakaway_n:
            return p, 0.0
        sign = 1.0 if u > 0.0 else -1.0
    else:
        sign = 1.0 if v > 0.0 else -1.0
    stribeck = prm.stribeck_n * math.exp(-prm.stribeck_decay * sign * v)
    f0 = prm.viscous * v + sign * (prm.coulomb_n + stribeck)
    a = (prm.viscous - prm.stribeck_decay * stribeck) / prm.mass  # dF/dċ / m on this branch
    d0 = (u - f0) / prm.mass
    phi1, phi2 = _phi(a, h)
    v1 = v + d0 * phi1
    if v1 * sign < 0.0:  # only from v != 0: the velocity would cross zero
        t_stop = _stop_time(v, d0, a, h)
        p_stop = p + v * t_stop + d0 * _phi(a, t_stop)[1]
        if t_stop < h:
            return substep(p_stop, 0.0, u, h - t_stop, prm)
        return p_stop, 0.0
    return p + v * h + d0 * phi2, v1


# --------------------------------------------------------------------------- the plant


def paper001_axes(names: Sequence[str],
                  overrides: Mapping[str, Mapping[str, Any]]) -> tuple[MassFrictionAxisConfig, ...]:
    """Table 1's axes (Z = Y) with ``overrides`` applied; an axis the paper lacks lists the valid ones."""
    axes = []
    for name in names:
        base = PAPER001_AXES.get(name.lower())
        if base is None:
            raise ConfigError(f"axes: paper001 has axes {sorted(PAPER001_AXES)}, got {name!r}")
        values = {**base, **overrides.get(name, {}), "name": name}
        axes.append(_axis_config(values, f"axis_overrides.{name}"))
    return tuple(axes)


def _axis_config(values: Mapping[str, Any], context: str) -> MassFrictionAxisConfig:
    """Build one axis config; every error names where the value came from (``axis_overrides.x.mass``)."""
    try:
        return build_config(MassFrictionAxisConfig, values, context=context)
    except ConfigError as err:
        if str(err).startswith(context):
            raise
        raise ConfigError(f"{context}.{err}") from err


class MassFrictionPlant:
    """Mass-friction axes of Eqs. 18-19 stepped together (a :class:`~cnc_plant_sim.models.plant.Plant`).

    Parameters
    ----------
    model : str
        The model's name (for :meth:`describe`).
    axes : tuple of MassFrictionAxisConfig
        The axes in command order, in the model's length unit.
    options : MassFrictionOptions
        Length unit and cutting load.
    substeps : int
        Sub-steps per step, >= 1.
    """

    command_unit = "N"

    def __init__(self, model: str, axes: tuple[MassFrictionAxisConfig, ...], options: MassFrictionOptions,
                 substeps: int = 1) -> None:
        self.model, self.axis_configs, self.options = model, axes, options
        self.axis_names = tuple(c.name for c in axes)
        self.substeps = int(substeps)
        self._params = [axis_params(c) for c in axes]
        self._m_per_unit = options.m_per_unit
        self._load = CUTTING_LOADS[options.cutting_load]
        self.reset()

    def reset(self, positions_m: Sequence[float] | None = None) -> None:
        """Put every axis at rest at ``positions_m`` (shape (n,), m; None: 0)."""
        values = [0.0] * len(self._params) if positions_m is None else list(positions_m)
        check_length(self.axis_names, "positions_m", values)
        for name, value in zip(self.axis_names, values):
            if not is_finite_number(value):
                raise FaultError(f"axis {name}: reset position_m must be finite, got {value!r}")
        self._pos = [float(v) / self._m_per_unit for v in values]
        self._vel = [0.0] * len(values)
        self._friction = [0.0] * len(values)
        self._cutting = [0.0] * len(values)

    def step(self, commands: Sequence[float], dt_s: float) -> None:
        """Hold ``commands`` (shape (n,), N, axis order) for ``dt_s`` [s].

        Raises
        ------
        FaultError
            On a wrong count, a non-finite command (naming the axis), a bad
            ``dt_s`` or a non-finite result; no axis moves then.
        """
        check_step(self.axis_names, commands, dt_s)
        scale, n, h = self._m_per_unit, self.substeps, dt_s / self.substeps
        cutting = self._load([v * scale for v in self._vel], self.options)
        positions, velocities, frictions = [], [], []
        for name, p, v, u, load, prm in zip(self.axis_names, self._pos, self._vel, commands, cutting, self._params):
            net = float(u) - load
            for _ in range(n):
                p, v = substep(p, v, net, h, prm)
            if p - p != 0.0 or v - v != 0.0:  # a NaN or an infinity
                raise FaultError(f"axis {name}: state became non-finite (c {p}, dc/dt {v})")
            positions.append(p)
            velocities.append(v)
            frictions.append(friction_after(v, net, prm))
        self._pos, self._vel, self._friction, self._cutting = positions, velocities, frictions, cutting

    def positions_m(self) -> npt.NDArray[np.float64]:
        """Axis positions, shape (n,), m."""
        return np.array(self._pos) * self._m_per_unit

    def velocities_m_s(self) -> npt.NDArray[np.float64]:
        """Axis velocities, shape (n,), m/s."""
        return np.array(self._vel) * self._m_per_unit

    def state(self) -> tuple[list[float], list[float]]:
        """Positions [m] and velocities [m/s] as lists in axis order (the per-tick read)."""
        scale = self._m_per_unit
        return [p * scale for p in self._pos], [v * scale for v in self._vel]

    def forces_n(self) -> npt.NDArray[np.float64]:
        """Friction after the last step (at rest: the force it balances) plus cutting load per axis, shape (n,), N."""
        return np.array(self._friction) + np.array(self._cutting)

    def describe(self) -> dict[str, Any]:
        """The plant as built (plain types); ``axes`` and ``options`` rebuild it as overrides and ``mass_friction``."""
        return {
            "model": self.model,
            "command_unit": self.command_unit,
            "length_unit": self.options.length_unit,
            "integration": "zero-order hold; friction linearised per sub-step, linear ODE solved exactly",
            "substeps": self.substeps,
            "variation": "none (paper 001 draws no parameters)",
            "options": config_values(self.options),
            "axes": {c.name: {k: v for k, v in config_values(c).items() if k != "name"} for c in self.axis_configs},
            "breakaway_n": {c.name: c.breakaway_n for c in self.axis_configs},
        }
