"""Axes under a closed velocity loop: the command is a velocity [m/s] (papers 002 and 003).

The position loop (the servo's ``p`` law: paper 002's P "cascade", paper
003's position-loop gain k) sends a velocity command u per axis. Each axis is
a closed velocity loop from u to the axis velocity v, chosen by ``loop``
(:data:`LOOPS`):

``pi``
    A PI velocity loop over a rigid motor (paper 002 Fig. 1, paper 003 Eq. 1),
    state ``[x, v, z]`` with z the loop's integral of ``w − v``::

        dv/dt = c (K_sp (w − v) + K_si z),   dz/dt = w − v,   dx/dt = v

    c = K_t/J (``torque_per_inertia``), K_sp = ``kp`` (paper 003's K2), K_si =
    ``ki`` (K1). The input w is held over each sub-step and the linear system
    is integrated **exactly** (matrix exponential of the augmented system,
    ``scipy.linalg.expm``, computed once per sub-step length).
``discrete``
    An identified closed loop in z⁻¹ (paper 002 Eqs. 35-36,
    :data:`~cnc_contour_control.core.velocity_models.PAPER002_MODELS`), valid only
    at its own sample time: a step of another length is refused naming both.
    It needs a one-sample delay (numerator[0] = 0); the position integrates
    the velocity samples by the trapezoid rule.

The disturbance acts at the plant input, as paper 002 writes it (T_L: "T_F of
Eq. 3 as an equivalent disturbance at the plant input"), in the command's own
unit: ``w = u − d`` with ``d = F_fric + A sin(φ(t) + θ)``. φ advances at
``2π f_d``, ``f_d = spindle_rpm · flutes / 60`` (Eq. 2); the spindle speed
follows ``spindle_schedule_t_s``/``spindle_schedule_rpm``
(:class:`~cnc_contour_control.axis.spindle.SpindleSchedule`: piecewise constant,
φ continuous across a change), identical in the engine and the graph because
both build the plant from the same config and step it with the same periods.
Friction is Coulomb with stiction in Karnopp's form: while ``|v| <=
stick_velocity_mm_s`` the friction balances the rest of the input up to the
breakaway level ``stiction_mm_s``; beyond it, ``coulomb_mm_s · sign(v)``. The
disturbance is evaluated at each (sub-)step's start and held.

The encoder reports positions rounded to ``encoder_pulse_m`` (paper 002's
pulse, 1/2.4 µm, by default; 0: off); velocities are the loop's own.
"""
from __future__ import annotations

import cmath
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import check_ranges, config_values, param
from cnc_contour_control.core.units import M_PER_MM, M_PER_PULSE_PAPER002
from cnc_contour_control.core.velocity_models import (
    PAPER002_MODELS,
    PAPER003_TORQUE_PER_INERTIA,
    DiscreteVelocityModel,
    PiVelocityLoop,
)
from cnc_plant_sim.models.periodic_load import SpindleFields, overridden_schedule
from cnc_plant_sim.models.step_checks import check_length, check_step, is_finite_number

#: Paper 003's table, "standard" column: K1 = K_si [Nm/rad], K2 = K_sp [Nm s/rad].
PAPER003_STANDARD_GAINS: dict[str, float] = {"ki": 101.121, "kp": 1.1396}
#: Relative tolerance on a discrete model's sample time.
SAMPLE_TIME_RTOL = 1.0e-9
_GAIN_RANGE = (0.0, 1.0e9)
_DIST_RANGE_MM_S = (0.0, 1.0e6)


@dataclass(frozen=True)
class VelocityLoopOptions(SpindleFields):
    """Model-wide options of the velocity-loop plants (the ``velocity_loop`` section of a plant config).

    Parameters
    ----------
    spindle_rpm, flutes, spindle_schedule_t_s, spindle_schedule_rpm
        The spindle speed w_s over the run and the tool's flutes l
        (:class:`~cnc_plant_sim.models.periodic_load.SpindleFields`).
    encoder_pulse_m : float
        Encoder resolution [m] (0: positions not quantised), in [0, 1e-3].
    """

    encoder_pulse_m: float = param(M_PER_PULSE_PAPER002, unit="m", low=0.0, high=1.0e-3, read_only=True,
                                   description="encoder resolution (0: off; paper 002: 1/2.4 um)")

    def __post_init__(self) -> None:
        self.check_fields("velocity_loop")


@dataclass(frozen=True)
class VelocityLoopAxisConfig:
    """One axis: its closed velocity loop and its input disturbance (command units, here mm/s).

    Parameters
    ----------
    name : str
        Axis name.
    loop : str
        One of :data:`LOOPS` (``pi`` or ``discrete``).
    torque_per_inertia : float
        c = K_t/J of the PI loop [rad/(s² · command unit)], in [1e-6, 1e9].
    kp, ki : float
        K_sp [per c] and K_si [per c · s] of the PI loop, kp in [0, 1e9], ki in [1e-12, 1e9].
    discrete_model : str
        Key of :data:`PAPER002_MODELS` for the ``discrete`` loop.
    coulomb_mm_s, stiction_mm_s : float
        Coulomb level and breakaway level (>= Coulomb) at the plant input [mm/s].
    stick_velocity_mm_s : float
        |v| at or below which the axis counts as sticking [mm/s], in [0, 1e3].
    disturbance_amplitude_mm_s : float
        A of Eq. 3 at the plant input [mm/s], in [0, 1e6].
    disturbance_phase_rad : float
        θ of Eq. 3 [rad], in [-2π, 2π].
    """

    name: str = param(read_only=True, description="axis name")
    loop: str = param("pi", read_only=True, description="closed velocity loop: pi or discrete")
    torque_per_inertia: float = param(PAPER003_TORQUE_PER_INERTIA, low=1.0e-6, high=1.0e9, read_only=True,
                                      description="K_t/J of the PI loop")
    kp: float = param(PAPER003_STANDARD_GAINS["kp"], low=_GAIN_RANGE[0], high=_GAIN_RANGE[1], read_only=True,
                      description="proportional gain K_sp of the velocity loop (paper 003: K2)")
    ki: float = param(PAPER003_STANDARD_GAINS["ki"], low=1.0e-12, high=_GAIN_RANGE[1], read_only=True,
                      description="integral gain K_si of the velocity loop (paper 003: K1)")
    discrete_model: str = param("x", read_only=True, description="identified model of the discrete loop")
    coulomb_mm_s: float = param(0.0, unit="mm/s", low=_DIST_RANGE_MM_S[0], high=_DIST_RANGE_MM_S[1],
                                read_only=True, description="Coulomb friction at the plant input")
    stiction_mm_s: float = param(0.0, unit="mm/s", low=_DIST_RANGE_MM_S[0], high=_DIST_RANGE_MM_S[1],
                                 read_only=True, description="breakaway (stiction) level, >= coulomb_mm_s")
    stick_velocity_mm_s: float = param(0.01, unit="mm/s", low=0.0, high=1.0e3, read_only=True,
                                       description="|v| at or below which the axis sticks")
    disturbance_amplitude_mm_s: float = param(0.0, unit="mm/s", low=_DIST_RANGE_MM_S[0], high=_DIST_RANGE_MM_S[1],
                                              read_only=True, description="periodic disturbance amplitude A")
    disturbance_phase_rad: float = param(0.0, unit="rad", low=-2.0 * math.pi, high=2.0 * math.pi, read_only=True,
                                         description="periodic disturbance phase theta")

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"name must be a non-empty string, got {self.name!r}")
        require_choice("loop", self.loop, LOOPS)
        require_choice("discrete_model", self.discrete_model, PAPER002_MODELS)
        check_ranges(self)
        if self.stiction_mm_s < self.coulomb_mm_s:
            raise ConfigError(f"stiction_mm_s must be >= coulomb_mm_s ({self.coulomb_mm_s}), "
                              f"got {self.stiction_mm_s}")


# --------------------------------------------------------------------------- the two loops


def pi_loop_from_discrete(model: DiscreteVelocityModel) -> PiVelocityLoop:
    """The continuous PI loop whose poles are ``model``'s (s = ln z / T), with K_t/J = 1.

    Matches an identified model's step response to a few per cent
    (``test_velocity_loop``): paper 002 selects its continuous form this way.
    """
    if len(model.denominator) != 3:
        raise ConfigError(f"a PI loop needs a second-order denominator, got {len(model.denominator) - 1}")
    poles = np.roots(model.denominator)
    s = [cmath.log(complex(p)) / model.sample_time_s for p in poles]
    return PiVelocityLoop(1.0, -(s[0] + s[1]).real, (s[0] * s[1]).real)


class PiLoopAxis:
    """The PI loop integrated exactly per sub-step (state [x m, v m/s, z m])."""

    def __init__(self, loop: PiVelocityLoop) -> None:
        self.loop = loop
        c = loop.torque_per_inertia
        self._a = np.array([[0.0, 1.0, 0.0], [0.0, -c * loop.kp, c * loop.ki], [0.0, -1.0, 0.0]])
        self._b = np.array([0.0, c * loop.kp, 1.0])
        self._maps: dict[float, tuple[tuple[float, ...], ...]] = {}
        self.reset(0.0)

    def reset(self, position_m: float) -> None:
        """At rest at ``position_m``."""
        self.x, self.v, self.z = position_m, 0.0, 0.0

    def _map(self, h_s: float) -> tuple[tuple[float, ...], ...]:
        """Rows of [Φ | Γ] for a sub-step ``h_s`` (exact ZOH), cached."""
        rows = self._maps.get(h_s)
        if rows is None:  # once per sub-step length: the import stays off the per-sample path
            from scipy.linalg import expm

            block = np.zeros((4, 4))
            block[:3, :3], block[:3, 3] = self._a * h_s, self._b * h_s
            rows = tuple(tuple(float(x) for x in row) for row in expm(block)[:3])
            self._maps[h_s] = rows
        return rows

    def substep(self, w: float, h_s: float) -> None:
        """Hold the loop input ``w`` [m/s] for ``h_s`` [s]."""
        (a0, a1, a2, g0), (b0, b1, b2, g1), (c0, c1, c2, g2) = self._map(h_s)
        x, v, z = self.x, self.v, self.z
        self.x = a0 * x + a1 * v + a2 * z + g0 * w
        self.v = b0 * x + b1 * v + b2 * z + g1 * w
        self.z = c0 * x + c1 * v + c2 * z + g2 * w


class DiscreteLoopAxis:
    """An identified closed loop: y(k+1) from w(k), direct form II transposed; x by the trapezoid rule."""

    def __init__(self, model: DiscreteVelocityModel) -> None:
        if model.numerator[0] != 0.0:
            raise ConfigError(f"numerator[0] must be 0 (a sampled loop has a one-sample delay), "
                              f"got {model.numerator[0]}")
        self.model = model
        n = max(len(model.numerator), len(model.denominator))
        self._b = list(model.numerator[1:]) + [0.0] * (n - len(model.numerator))
        self._a = list(model.denominator[1:]) + [0.0] * (n - len(model.denominator))
        self.reset(0.0)

    def reset(self, position_m: float) -> None:
        """At rest at ``position_m``."""
        self.x, self.v = position_m, 0.0
        self._state = [0.0] * len(self._a)

    def substep(self, w: float, h_s: float) -> None:
        """Hold ``w`` [m/s] for one sample ``h_s`` (the model's sample time, checked by the plant)."""
        s, b, a = self._state, self._b, self._a
        y = b[0] * w + s[0]
        state = [b[i + 1] * w + s[i + 1] - a[i] * y for i in range(len(s) - 1)]
        state.append(-a[-1] * y)
        self._state = state  # a new list: the plant's rollback keeps the old one
        self.x += 0.5 * h_s * (self.v + y)
        self.v = y


def _pi_axis(config: VelocityLoopAxisConfig) -> PiLoopAxis:
    return PiLoopAxis(PiVelocityLoop(config.torque_per_inertia, config.kp, config.ki))


def _discrete_axis(config: VelocityLoopAxisConfig) -> DiscreteLoopAxis:
    return DiscreteLoopAxis(PAPER002_MODELS[config.discrete_model])


#: Velocity loops by name: axis config -> the axis's loop.
LOOPS: dict[str, Callable[[VelocityLoopAxisConfig], PiLoopAxis | DiscreteLoopAxis]] = {
    "pi": _pi_axis,
    "discrete": _discrete_axis,
}


# --------------------------------------------------------------------------- the models' axes


def _paper002_nominal(name: str) -> dict[str, Any]:
    """Eqs. 35-36 (Z copies Y); the continuous form, if selected, has the model's poles."""
    key = "x" if name.lower() == "x" else "y"
    fitted = pi_loop_from_discrete(PAPER002_MODELS[key])
    return {"loop": "discrete", "discrete_model": key, "torque_per_inertia": fitted.torque_per_inertia,
            "kp": fitted.kp, "ki": fitted.ki}


def _paper003_nominal(name: str) -> dict[str, Any]:
    """Eq. 1 with K_t/J_m = 157 and the standard K1, K2 on every axis."""
    return {"loop": "pi", "torque_per_inertia": PAPER003_TORQUE_PER_INERTIA, **PAPER003_STANDARD_GAINS}


#: Nominal axis keys per model name: axis name -> keys of :class:`VelocityLoopAxisConfig`.
NOMINAL_AXES: dict[str, Callable[[str], dict[str, Any]]] = {
    "paper002": _paper002_nominal,
    "paper003": _paper003_nominal,
}


def velocity_loop_axes(model: str, names: Sequence[str],
                       overrides: Mapping[str, Mapping[str, Any]]) -> tuple[VelocityLoopAxisConfig, ...]:
    """The axes of ``model`` with ``overrides`` applied; errors name ``axis_overrides.<axis>.<key>``."""
    require_choice("model", model, NOMINAL_AXES)
    axes = []
    for name in names:
        context = f"axis_overrides.{name}"
        values = {**NOMINAL_AXES[model](name), **overrides.get(name, {}), "name": name}
        try:
            axes.append(build_config(VelocityLoopAxisConfig, values, context=context))
        except ConfigError as err:
            if str(err).startswith(context):
                raise
            raise ConfigError(f"{context}.{err}") from err
    return tuple(axes)


# --------------------------------------------------------------------------- the plant


class VelocityLoopPlant:
    """Velocity-commanded axes (a :class:`~cnc_plant_sim.models.plant.Plant`; commands in m/s).

    Parameters
    ----------
    model : str
        The model's name (for :meth:`describe`).
    axes : tuple of VelocityLoopAxisConfig
        The axes in command order.
    options : VelocityLoopOptions
        Spindle, flutes, schedule, encoder.
    substeps : int
        Sub-steps per step of the ``pi`` loops (the disturbance is held over each), >= 1.
    """

    command_unit = "m/s"

    def __init__(self, model: str, axes: tuple[VelocityLoopAxisConfig, ...], options: VelocityLoopOptions,
                 substeps: int = 1) -> None:
        self.model, self.axis_configs, self.options = model, axes, options
        self.axis_names = tuple(c.name for c in axes)
        self.substeps = int(substeps)
        self.schedule = options.schedule()
        self._loops = [LOOPS[c.loop](c) for c in axes]
        self._checked_dt_s = math.nan
        self.reset()

    def check_sample_time(self, dt_s: float) -> None:
        """Refuse a period the plant cannot take: a discrete loop's other sample time, f_d at or above Nyquist."""
        for config, loop in zip(self.axis_configs, self._loops):
            if isinstance(loop, DiscreteLoopAxis):
                own = loop.model.sample_time_s
                if abs(dt_s - own) > SAMPLE_TIME_RTOL * own:
                    raise ConfigError(f"axis {config.name}: discrete_model {config.discrete_model!r} holds only at "
                                      f"its sample time {own} s, got sample_time_s {dt_s}")
        nyquist_hz = 0.5 / dt_s
        for rpm, f_d in zip((self.options.spindle_rpm, *self.options.spindle_schedule_rpm),
                            self.schedule.frequencies_hz):
            if f_d >= nyquist_hz:
                raise ConfigError(f"velocity_loop.spindle_rpm: f_d = rpm * flutes / 60 must be < {nyquist_hz} Hz "
                                  f"(Nyquist at sample_time_s {dt_s}), got {f_d} Hz (rpm {rpm}, flutes "
                                  f"{self.options.flutes})")
        self._checked_dt_s = dt_s

    def reset(self, positions_m: Sequence[float] | None = None) -> None:
        """Every axis at rest at ``positions_m`` (shape (n,), m; None: 0); the run's time back to 0."""
        values = [0.0] * len(self._loops) if positions_m is None else list(positions_m)
        check_length(self.axis_names, "positions_m", values)
        for name, value in zip(self.axis_names, values):
            if not is_finite_number(value):
                raise FaultError(f"axis {name}: reset position_m must be finite, got {value!r}")
        for loop, value in zip(self._loops, values):
            loop.reset(float(value))
        self.time_s = 0.0
        self._disturbance = [0.0] * len(values)

    def set_spindle_rpm(self, spindle_rpm: float, sample_time_s: float) -> None:
        """Hold ``spindle_rpm`` from the present time on (a spindle override;
        :func:`~cnc_plant_sim.models.periodic_load.set_spindle_rpm`); f_d at or above Nyquist at ``sample_time_s``
        is a :class:`ConfigError`, nothing changed."""
        self.schedule = overridden_schedule(self.schedule, self.time_s, spindle_rpm, self.options.flutes,
                                            sample_time_s)

    def disturbance(self, index: int, velocity_m_s: float, command_m_s: float, t_s: float) -> float:
        """d = friction + A sin(φ(t) + θ) of axis ``index`` [m/s] (friction in Karnopp's form)."""
        config = self.axis_configs[index]
        periodic = config.disturbance_amplitude_mm_s * M_PER_MM * math.sin(
            self.schedule.phase_rad(t_s) + config.disturbance_phase_rad)
        if abs(velocity_m_s) > config.stick_velocity_mm_s * M_PER_MM:
            return periodic + math.copysign(config.coulomb_mm_s * M_PER_MM, velocity_m_s)
        level = config.stiction_mm_s * M_PER_MM
        return periodic + max(-level, min(level, command_m_s - periodic))

    def step(self, commands: Sequence[float], dt_s: float) -> None:
        """Hold ``commands`` (shape (n,), m/s) for ``dt_s`` [s].

        Raises
        ------
        FaultError
            On a wrong count, a non-finite command, a bad ``dt_s`` or a non-finite state; no axis moves then.
        ConfigError
            On a period the plant refuses (:meth:`check_sample_time`).
        """
        check_step(self.axis_names, commands, dt_s)
        if dt_s != self._checked_dt_s:
            self.check_sample_time(dt_s)
        saved = [vars(loop).copy() for loop in self._loops]
        try:
            self._advance(commands, dt_s)
        except FaultError:
            for loop, state in zip(self._loops, saved):
                vars(loop).update(state)
            raise
        self.time_s += dt_s

    def _advance(self, commands: Sequence[float], dt_s: float) -> None:
        for i, (loop, u) in enumerate(zip(self._loops, commands)):
            n = 1 if isinstance(loop, DiscreteLoopAxis) else self.substeps
            h, u = dt_s / n, float(u)
            for j in range(n):
                d = self.disturbance(i, loop.v, u, self.time_s + j * h)
                loop.substep(u - d, h)
            self._disturbance[i] = d
            if loop.x - loop.x != 0.0 or loop.v - loop.v != 0.0:
                raise FaultError(f"axis {self.axis_names[i]}: state became non-finite (x {loop.x}, v {loop.v})")

    def _encoder(self, position_m: float) -> float:
        pulse = self.options.encoder_pulse_m
        return math.floor(position_m / pulse + 0.5) * pulse if pulse > 0.0 else position_m

    def positions_m(self) -> npt.NDArray[np.float64]:
        """Encoder positions, shape (n,), m (rounded to ``encoder_pulse_m``)."""
        return np.array([self._encoder(loop.x) for loop in self._loops])

    def velocities_m_s(self) -> npt.NDArray[np.float64]:
        """Axis velocities, shape (n,), m/s."""
        return np.array([loop.v for loop in self._loops])

    def state(self) -> tuple[list[float], list[float]]:
        """Encoder positions [m] and velocities [m/s] as lists (the per-tick read)."""
        return [self._encoder(loop.x) for loop in self._loops], [loop.v for loop in self._loops]

    def true_positions_m(self) -> list[float]:
        """Positions before the encoder [m]."""
        return [loop.x for loop in self._loops]

    def disturbances_m_s(self) -> list[float]:
        """The input disturbance d of the last sub-step per axis [m/s]."""
        return list(self._disturbance)

    def forces_n(self) -> None:
        """No force: the disturbance is a velocity-command equivalent."""
        return None

    def describe(self) -> dict[str, Any]:
        """The plant as built (plain types); ``axes`` and ``options`` rebuild it as overrides and ``velocity_loop``."""
        return {
            "model": self.model,
            "command_unit": self.command_unit,
            "integration": "pi: exact ZOH per sub-step (matrix exponential); discrete: the model at its sample "
                           "time, position by the trapezoid rule; disturbance held per (sub-)step",
            "substeps": self.substeps,
            "variation": "none",
            "options": config_values(self.options),
            "axes": {c.name: {k: v for k, v in config_values(c).items() if k != "name"} for c in self.axis_configs},
        }
