"""Friction models of a feed drive: force in drive units (DAC) against velocity in mm/s.

A model gives the kinetic friction of a moving axis, ``force(velocity_mm_s)``,
and the static (breakaway) levels of an axis at rest: it stays at rest while
the command ``u`` satisfies ``breakaway_negative <= u <= breakaway_positive``.
The positive branch (``V >= 0``) and the negative branch (``V < 0``) are
separate functions, so the friction may jump at ``V = 0`` (Coulomb friction);
each breakaway level is its branch's value at ``V = 0``.

Models come from the registry :data:`FRICTIONS` by name; each factory takes a
params mapping and refuses unknown keys. Every model has a ``scale`` factor
(the paper's ±8 % friction variation multiplies it).

Registered models
-----------------
``paper000_x``, ``paper000_y``
    Paper 000, Eq. (15): a quadratic in V for ``|V| < 12`` mm/s and a constant
    beyond. The equation is taken literally, including the small jumps it has
    at ``|V| = 12`` (X: 13.77 → 13.95 and −12.03 → −11.84). Params: ``scale``.
``coulomb_viscous``
    ``sign(V)·(F_c + (F_s − F_c)·exp(−(V/V_s)²)) + b·V``. Params:
    ``coulomb_dac``, ``viscous_dac_per_mm_s``, ``static_dac`` (defaults to
    ``coulomb_dac``), ``stribeck_velocity_mm_s`` (0: no Stribeck curve, the
    static level is then only the breakaway level), ``scale``.
``table``
    Linear interpolation in measured points (a friction identification writes
    these; see :meth:`TableFriction.from_arrays` and
    :meth:`TableFriction.to_params`). Points with ``V >= 0`` form the positive
    branch, points with ``V <= 0`` the negative one; each branch is held
    constant beyond its end points. Params: ``velocity_mm_s``, ``force_dac``,
    ``breakaway_positive_dac``, ``breakaway_negative_dac`` (default: the
    branch's value at V = 0), ``scale``.
``none``
    No friction. Params: ``scale`` (ignored).

Besides ``force``, every model gives ``linearise(velocity_mm_s, direction)``
→ ``(force, slope)`` with the slope ``dF/dV`` in DAC per mm/s of the branch
chosen by ``direction`` (+1 or −1); the axis integrator uses it.
"""
from __future__ import annotations

import abc
import bisect
import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.config import (
    build_config,
    require_choice,
    require_finite,
    require_non_negative,
)
from cnc_contour_control.core.errors import ConfigError

#: A friction factory: params mapping -> model.
FrictionFactory = Callable[[Mapping[str, Any]], "FrictionModel"]


class FrictionModel(abc.ABC):
    """Friction force against velocity, with separate positive and negative branches.

    Subclasses are frozen dataclasses with a ``scale`` field.
    """

    scale: float

    @abc.abstractmethod
    def linearise(self, velocity_mm_s: float, direction: int) -> tuple[float, float]:
        """Force and slope of the branch ``direction`` at ``velocity_mm_s``.

        Parameters
        ----------
        velocity_mm_s : float
            Axis velocity [mm/s].
        direction : int
            +1 selects the positive branch (V >= 0), −1 the negative branch.

        Returns
        -------
        tuple of float
            ``(force_dac, slope_dac_per_mm_s)``, scaled by ``scale``.
        """

    def force(self, velocity_mm_s: float) -> float:
        """Kinetic friction [DAC units] at ``velocity_mm_s`` [mm/s] (V = 0 takes the positive branch)."""
        return self.linearise(velocity_mm_s, 1 if velocity_mm_s >= 0.0 else -1)[0]

    @property
    def breakaway_positive(self) -> float:
        """Static friction level [DAC units] a command must exceed to start positive motion."""
        return self.linearise(0.0, 1)[0]

    @property
    def breakaway_negative(self) -> float:
        """Static friction level [DAC units] a command must fall below to start negative motion."""
        return self.linearise(0.0, -1)[0]

    def scaled(self, factor: float) -> FrictionModel:
        """A copy with ``scale`` multiplied by ``factor`` (>= 0)."""
        factor = require_non_negative("friction scale factor", factor)
        return dataclasses.replace(self, scale=self.scale * factor)  # type: ignore[type-var]  # every model is a frozen dataclass


def _check_scale(scale: float) -> float:
    return require_non_negative("scale", scale)


# --------------------------------------------------------------------------- paper 000


@dataclass(frozen=True)
class PiecewiseQuadraticFriction(FrictionModel):
    """Quadratic branches for ``|V| < limit_speed_mm_s`` and constants beyond (paper 000, Eq. 15).

    Parameters
    ----------
    positive_coefficients, negative_coefficients : tuple of 3 floats
        ``(c2, c1, c0)`` of ``c2·V² + c1·V + c0`` [DAC, V in mm/s] for
        ``0 <= V < limit`` and ``−limit <= V < 0``.
    positive_high_dac, negative_high_dac : float
        Constant force for ``V >= limit`` and ``V < −limit`` [DAC].
    limit_speed_mm_s : float
        Speed where the quadratics end [mm/s].
    scale : float
        Multiplies every force.
    """

    positive_coefficients: tuple[float, float, float]
    negative_coefficients: tuple[float, float, float]
    positive_high_dac: float
    negative_high_dac: float
    limit_speed_mm_s: float = 12.0
    scale: float = 1.0

    def __post_init__(self) -> None:
        _check_scale(self.scale)
        if self.limit_speed_mm_s <= 0.0:
            raise ConfigError(f"limit_speed_mm_s must be > 0, got {self.limit_speed_mm_s!r}")
        if self.breakaway_negative > self.breakaway_positive:
            raise ConfigError(
                f"breakaway_negative must be <= breakaway_positive ({self.breakaway_positive}), "
                f"got {self.breakaway_negative}"
            )

    def linearise(self, velocity_mm_s: float, direction: int) -> tuple[float, float]:
        """Force and slope of the chosen branch (see :meth:`FrictionModel.linearise`)."""
        if direction > 0:
            if velocity_mm_s >= self.limit_speed_mm_s:
                return self.scale * self.positive_high_dac, 0.0
            c2, c1, c0 = self.positive_coefficients
        else:
            if velocity_mm_s < -self.limit_speed_mm_s:
                return self.scale * self.negative_high_dac, 0.0
            c2, c1, c0 = self.negative_coefficients
        v = velocity_mm_s
        return self.scale * ((c2 * v + c1) * v + c0), self.scale * (2.0 * c2 * v + c1)


@dataclass(frozen=True)
class _ScaleParams:
    """The only param of a fixed (paper) friction model."""

    scale: float = 1.0

    def __post_init__(self) -> None:
        _check_scale(self.scale)


def paper000_x(params: Mapping[str, Any] | None = None) -> PiecewiseQuadraticFriction:
    """Paper 000 Eq. (15), X axis; params: ``scale``."""
    scale = build_config(_ScaleParams, params, context="paper000_x").scale
    return PiecewiseQuadraticFriction(
        (0.05, -1.16, 20.49), (-0.04, -1.00, -18.27), 13.95, -11.84, 12.0, scale
    )


def paper000_y(params: Mapping[str, Any] | None = None) -> PiecewiseQuadraticFriction:
    """Paper 000 Eq. (15), Y axis; params: ``scale``."""
    scale = build_config(_ScaleParams, params, context="paper000_y").scale
    return PiecewiseQuadraticFriction(
        (0.04, -1.12, 19.99), (-0.02, -0.68, -16.84), 12.76, -11.80, 12.0, scale
    )


# --------------------------------------------------------------------------- Coulomb + viscous


@dataclass(frozen=True)
class CoulombViscousFriction(FrictionModel):
    """Symmetric Coulomb + viscous friction with an optional Stribeck curve.

    ``F(V) = sign(V)·(F_c + (F_s − F_c)·exp(−(V/V_s)²)) + b·V``, all times ``scale``.

    Parameters
    ----------
    coulomb_dac : float
        Coulomb level F_c [DAC], >= 0.
    viscous_dac_per_mm_s : float
        Viscous coefficient b [DAC per mm/s], >= 0.
    static_dac : float or None
        Static (breakaway) level F_s [DAC], >= 0; None means ``coulomb_dac``.
    stribeck_velocity_mm_s : float
        Stribeck velocity V_s [mm/s], >= 0; 0 means no Stribeck curve.
    scale : float
        Multiplies every force.
    """

    coulomb_dac: float = 0.0
    viscous_dac_per_mm_s: float = 0.0
    static_dac: float | None = None
    stribeck_velocity_mm_s: float = 0.0
    scale: float = 1.0

    def __post_init__(self) -> None:
        require_non_negative("coulomb_dac", self.coulomb_dac)
        require_non_negative("viscous_dac_per_mm_s", self.viscous_dac_per_mm_s)
        require_non_negative("stribeck_velocity_mm_s", self.stribeck_velocity_mm_s)
        _check_scale(self.scale)
        if self.static_dac is None:
            object.__setattr__(self, "static_dac", float(self.coulomb_dac))
        require_non_negative("static_dac", self.static_dac)  # type: ignore[arg-type]  # a float from here on

    def linearise(self, velocity_mm_s: float, direction: int) -> tuple[float, float]:
        """Force and slope of the chosen branch (see :meth:`FrictionModel.linearise`)."""
        sign = 1.0 if direction > 0 else -1.0
        v = velocity_mm_s
        level, level_slope = self._level(v)
        force = sign * level + self.viscous_dac_per_mm_s * v
        slope = sign * level_slope + self.viscous_dac_per_mm_s
        return self.scale * force, self.scale * slope

    def _level(self, v: float) -> tuple[float, float]:
        """Unsigned Coulomb/Stribeck level and its derivative at ``v``."""
        vs = self.stribeck_velocity_mm_s
        excess = self.static_dac - self.coulomb_dac  # type: ignore[operator]  # static_dac: set in __post_init__
        if vs == 0.0:
            return (self.static_dac if v == 0.0 else self.coulomb_dac), 0.0  # type: ignore[return-value]  # static_dac is set
        bump = excess * math.exp(-((v / vs) ** 2))
        return self.coulomb_dac + bump, bump * (-2.0 * v / (vs * vs))


def coulomb_viscous(params: Mapping[str, Any] | None = None) -> CoulombViscousFriction:
    """Coulomb + viscous (+ Stribeck) friction; see :class:`CoulombViscousFriction`."""
    return build_config(CoulombViscousFriction, params, context="coulomb_viscous")


# --------------------------------------------------------------------------- table


def _float_tuple(name: str, values: Sequence[float] | npt.ArrayLike) -> tuple[float, ...]:
    try:
        items = [float(x) for x in np.asarray(values, dtype=float).ravel()]
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{name} must be a sequence of numbers, got {values!r}") from err
    for item in items:
        require_finite(name, item)
    return tuple(items)


def _interp(xs: list[float], ys: list[float], x: float) -> tuple[float, float]:
    """Linear interpolation with constant extrapolation; returns (value, slope)."""
    if x <= xs[0]:
        return ys[0], 0.0
    if x >= xs[-1]:
        return ys[-1], 0.0
    i = bisect.bisect_right(xs, x)
    slope = (ys[i] - ys[i - 1]) / (xs[i] - xs[i - 1])
    return ys[i - 1] + slope * (x - xs[i - 1]), slope


@dataclass(frozen=True)
class TableFriction(FrictionModel):
    """Friction interpolated linearly in measured points, one branch per direction.

    Parameters
    ----------
    velocity_mm_s : tuple of float, shape (n,)
        Strictly increasing velocities [mm/s]; at least one ``>= 0`` and one ``<= 0``.
    force_dac : tuple of float, shape (n,)
        Friction at those velocities [DAC].
    breakaway_positive_dac, breakaway_negative_dac : float or None
        Static levels [DAC]; None means the branch's value at V = 0.
    scale : float
        Multiplies every force.
    """

    velocity_mm_s: tuple[float, ...]
    force_dac: tuple[float, ...]
    breakaway_positive_dac: float | None = None
    breakaway_negative_dac: float | None = None
    scale: float = 1.0

    def __post_init__(self) -> None:
        velocity = _float_tuple("velocity_mm_s", self.velocity_mm_s)
        force = _float_tuple("force_dac", self.force_dac)
        object.__setattr__(self, "velocity_mm_s", velocity)
        object.__setattr__(self, "force_dac", force)
        _check_table(velocity, force)
        _check_scale(self.scale)
        self._set_branches(velocity, force)
        for name in ("breakaway_positive_dac", "breakaway_negative_dac"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, require_finite(name, value))
        if self.breakaway_negative > self.breakaway_positive:
            raise ConfigError(
                f"breakaway_negative_dac must be <= breakaway_positive_dac "
                f"({self.breakaway_positive}), got {self.breakaway_negative}"
            )

    def _set_branches(self, velocity: tuple[float, ...], force: tuple[float, ...]) -> None:
        pos = [(v, f) for v, f in zip(velocity, force) if v >= 0.0]
        neg = [(v, f) for v, f in zip(velocity, force) if v <= 0.0]
        object.__setattr__(self, "_pos_v", [v for v, _ in pos])
        object.__setattr__(self, "_pos_f", [f for _, f in pos])
        object.__setattr__(self, "_neg_v", [v for v, _ in neg])
        object.__setattr__(self, "_neg_f", [f for _, f in neg])

    @classmethod
    def from_arrays(
        cls,
        velocity_mm_s: npt.ArrayLike,
        force_dac: npt.ArrayLike,
        breakaway_positive_dac: float | None = None,
        breakaway_negative_dac: float | None = None,
        scale: float = 1.0,
    ) -> TableFriction:
        """Build a table from arrays of shape (n,) [mm/s] and (n,) [DAC], sorting by velocity."""
        v = np.asarray(velocity_mm_s, dtype=float).ravel()
        f = np.asarray(force_dac, dtype=float).ravel()
        if v.shape != f.shape:
            raise ConfigError(
                f"force_dac must have the length of velocity_mm_s ({v.size}), got {f.size}"
            )
        order = np.argsort(v, kind="stable")
        return cls(tuple(v[order]), tuple(f[order]), breakaway_positive_dac,
                   breakaway_negative_dac, scale)

    def to_params(self) -> dict[str, Any]:
        """The params mapping (plain lists and floats, YAML-ready) that rebuilds this table."""
        params: dict[str, Any] = {
            "velocity_mm_s": list(self.velocity_mm_s),
            "force_dac": list(self.force_dac),
            "scale": float(self.scale),
        }
        for name in ("breakaway_positive_dac", "breakaway_negative_dac"):
            if getattr(self, name) is not None:
                params[name] = float(getattr(self, name))
        return params

    def linearise(self, velocity_mm_s: float, direction: int) -> tuple[float, float]:
        """Force and slope of the chosen branch (see :meth:`FrictionModel.linearise`)."""
        if direction > 0:
            if velocity_mm_s == 0.0 and self.breakaway_positive_dac is not None:
                return self.scale * self.breakaway_positive_dac, 0.0
            force, slope = _interp(self._pos_v, self._pos_f,  # type: ignore[attr-defined]  # set by __post_init__
                                   velocity_mm_s)
        else:
            if velocity_mm_s == 0.0 and self.breakaway_negative_dac is not None:
                return self.scale * self.breakaway_negative_dac, 0.0
            force, slope = _interp(self._neg_v, self._neg_f,  # type: ignore[attr-defined]  # set by __post_init__
                                   velocity_mm_s)
        return self.scale * force, self.scale * slope


def _check_table(velocity: tuple[float, ...], force: tuple[float, ...]) -> None:
    if len(force) != len(velocity):
        raise ConfigError(
            f"force_dac must have the length of velocity_mm_s ({len(velocity)}), got {len(force)}"
        )
    for prev, cur in zip(velocity, velocity[1:]):
        if cur <= prev:
            raise ConfigError(f"velocity_mm_s must be strictly increasing, got {cur} after {prev}")
    if not velocity or velocity[-1] < 0.0:
        raise ConfigError(f"velocity_mm_s needs a point >= 0 (positive branch), got {list(velocity)}")
    if velocity[0] > 0.0:
        raise ConfigError(f"velocity_mm_s needs a point <= 0 (negative branch), got {list(velocity)}")


def table(params: Mapping[str, Any] | None = None) -> TableFriction:
    """Tabulated friction; see :class:`TableFriction`."""
    return build_config(TableFriction, params, context="table")


# --------------------------------------------------------------------------- none


@dataclass(frozen=True)
class NoFriction(FrictionModel):
    """Zero friction (``scale`` accepted and ignored)."""

    scale: float = 1.0

    def __post_init__(self) -> None:
        _check_scale(self.scale)

    def linearise(self, velocity_mm_s: float, direction: int) -> tuple[float, float]:
        """Always ``(0.0, 0.0)``."""
        return 0.0, 0.0


def no_friction(params: Mapping[str, Any] | None = None) -> NoFriction:
    """No friction; params: ``scale`` (ignored)."""
    return build_config(NoFriction, params, context="none")


#: Friction models by name.
FRICTIONS: dict[str, FrictionFactory] = {
    "paper000_x": paper000_x,
    "paper000_y": paper000_y,
    "coulomb_viscous": coulomb_viscous,
    "table": table,
    "none": no_friction,
}


#: The config class whose fields are each model's params (a fixed paper model takes only ``scale``).
FRICTION_CONFIGS: dict[str, type] = {
    "paper000_x": _ScaleParams,
    "paper000_y": _ScaleParams,
    "coulomb_viscous": CoulombViscousFriction,
    "table": TableFriction,
    "none": NoFriction,
}


def friction_config_class(name: str) -> type:
    """The class whose fields are the params of the friction model ``name`` (an unknown name lists the valid ones)."""
    require_choice("friction", name, FRICTION_CONFIGS)
    return FRICTION_CONFIGS[name]


def make_friction(name: str, params: Mapping[str, Any] | None = None) -> FrictionModel:
    """Build the friction model ``name`` from ``params``; an unknown name lists the valid ones."""
    require_choice("friction", name, FRICTIONS)
    return FRICTIONS[name](params or {})
