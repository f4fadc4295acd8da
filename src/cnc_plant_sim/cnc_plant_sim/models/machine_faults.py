"""Machine faults between the motor and the tool: what a ballbar measures and the servo never sees (ROS-free).

The servo feeds back on the motor-side position (``positions_m()``, semi-closed
loop); the faults act only on the *tool* position (``tool_positions_m()``).
A drive gain error ``g_i`` scales the command the axis receives, ``(1 + g_i)·u_i``
(the position loop's gain on that axis becomes ``(1 + g_i)·k``: a servo
mismatch made by the machine, not by the servo's settings).
Per axis ``i``, from the motor position ``m_i`` [m], in this order::

    table_i = play(m_i)                       backlash b_i: the table follows the motor through a
                                              dead band of width b_i (a hysteresis, the play operator)
    p_i     = table_i · (1 + s_i)             scale error s_i [ppm · 1e-6] about the machine zero
            + A_i · sin(2π · table_i / P_i)   cyclic (lead-screw pitch) error, amplitude A_i, pitch P_i
    p_a    += α · p_b                         squareness α [urad · 1e-6] of the pair (a, b): a reads a + α·b

The play operator: the table stays where it is while ``|m − table| <= b/2``
and is dragged along at ``m ∓ b/2`` beyond; at reset the table is at the
motor (in the middle of the band). The table follows the motor sampled at the
plant's steps (the play is rate-independent: exact while the motor moves one
way within a step). The squareness sign is the one
:mod:`cnc_tools.analysis.ballbar` reports as positive.

:class:`FaultedPlant` wraps any plant of :data:`cnc_plant_sim.models.plant.PLANTS`
and adds ``tool_positions_m()``; :func:`tool_positions_m` gives any plant's
tool position (the motor's when it has no faults).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, config_values, param

__all__ = ["AxisFaults", "FaultedPlant", "MachineFaults", "ToolMap", "apply_faults", "tool_positions_m"]

M_PER_UM = 1.0e-6
M_PER_MM = 1.0e-3
PER_PPM = 1.0e-6
RAD_PER_URAD = 1.0e-6


@dataclass(frozen=True)
class AxisFaults:
    """One axis's faults between motor and tool.

    Parameters
    ----------
    backlash_um : float
        Width of the dead band the table follows the motor through [um], in [0, 1e4].
    scale_ppm : float
        Scale error of the axis [ppm]: the tool reads ``(1 + s)·x``, in [-1e4, 1e4].
    cyclic_amplitude_um : float
        Amplitude of the lead-screw pitch error ``A sin(2π x / P)`` [um], in [0, 1e3].
    cyclic_pitch_mm : float
        Its period ``P`` along the axis (the screw's pitch) [mm], in [1e-3, 1e4].
    drive_gain_pct : float
        Gain error of the drive [%]: the axis receives ``(1 + g)·u`` for the command ``u``, in [-50, 100].
    """

    backlash_um: float = param(0.0, unit="um", low=0.0, high=1.0e4, read_only=True,
                               description="dead band between motor and table (semi-closed loop)")
    scale_ppm: float = param(0.0, unit="ppm", low=-1.0e4, high=1.0e4, read_only=True,
                             description="scale error: the tool reads (1 + s) x")
    cyclic_amplitude_um: float = param(0.0, unit="um", low=0.0, high=1.0e3, read_only=True,
                                       description="amplitude of the cyclic (lead-screw pitch) error")
    cyclic_pitch_mm: float = param(5.0, unit="mm", low=1.0e-3, high=1.0e4, read_only=True,
                                   description="period of the cyclic error along the axis (screw pitch)")
    drive_gain_pct: float = param(0.0, unit="%", low=-50.0, high=100.0, read_only=True,
                                  description="drive gain error: the axis receives (1 + g) times the command")

    def __post_init__(self) -> None:
        check_ranges(self)

    @property
    def active(self) -> bool:
        """True when the axis has any fault."""
        return bool(self.backlash_um or self.scale_ppm or self.cyclic_amplitude_um or self.drive_gain_pct)


@dataclass(frozen=True)
class MachineFaults:
    """The ``plant.faults`` section: per-axis faults and the squareness of one axis pair.

    Parameters
    ----------
    squareness_urad : float
        Squareness error α [urad] of ``squareness_axes`` (a, b): a reads ``a + α·b``, in [-1e5, 1e5].
    squareness_axes : tuple of str
        The pair (a, b), two different axes of the plant.
    axes : Mapping[str, AxisFaults]
        Per axis name, its :class:`AxisFaults` (a mapping is validated into one); axes absent have none.
    """

    squareness_urad: float = param(0.0, unit="urad", low=-1.0e5, high=1.0e5, read_only=True,
                                   description="squareness error: axis a reads a + alpha b")
    squareness_axes: tuple[str, ...] = param(("x", "y"), read_only=True,
                                             description="the axis pair (a, b) of the squareness error")
    axes: Mapping[str, AxisFaults] = param(default_factory=dict, read_only=True,
                                           description="per-axis faults (backlash, scale, cyclic error)")

    def __post_init__(self) -> None:
        check_ranges(self, "faults")
        pair = self.squareness_axes
        if isinstance(pair, str) or not isinstance(pair, Sequence) or len(pair) != 2 or pair[0] == pair[1]:
            raise ConfigError(f"faults.squareness_axes must be two different axis names, got {pair!r}")
        object.__setattr__(self, "squareness_axes", tuple(pair))
        if not isinstance(self.axes, Mapping):
            raise ConfigError(f"faults.axes must map axis names to mappings, got {self.axes!r}")
        object.__setattr__(self, "axes", {str(name): _axis_faults(name, value) for name, value in self.axes.items()})

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any] | None, context: str = "faults") -> MachineFaults:
        """Build from a mapping; unknown keys are an error listing the valid ones."""
        if mapping is not None and not isinstance(mapping, Mapping):
            raise ConfigError(f"{context} must be a mapping, got {mapping!r}")
        return build_config(cls, mapping, context=context)

    @property
    def active(self) -> bool:
        """True when any fault is configured (the plant then publishes the tool position)."""
        return bool(self.squareness_urad) or any(a.active for a in self.axes.values())

    def check_axes(self, axes: Sequence[str]) -> None:
        """Raise ConfigError naming an axis of the faults that is not one of the plant's ``axes``."""
        unknown = sorted(set(self.axes) - set(axes))
        if unknown:
            raise ConfigError(f"faults.axes.{unknown[0]}: unknown axis; valid axes are {list(axes)}")
        if self.squareness_urad and not set(self.squareness_axes) <= set(axes):
            raise ConfigError(f"faults.squareness_axes must be axes of the plant {list(axes)}, "
                              f"got {list(self.squareness_axes)}")


def _axis_faults(name: Any, value: Any) -> AxisFaults:
    if isinstance(value, AxisFaults):
        return value
    if not isinstance(value, Mapping):
        raise ConfigError(f"faults.axes.{name} must be a mapping, got {value!r}")
    return build_config(AxisFaults, value, context=f"faults.axes.{name}")


def play(motor_m: float, table_m: float, backlash_m: float) -> float:
    """The table position after the motor moved to ``motor_m`` (play operator of width ``backlash_m``), m."""
    half = 0.5 * backlash_m
    return min(max(table_m, motor_m - half), motor_m + half)


class ToolMap:
    """The tool position of one tick from its table positions (module docstring), the factors computed once.

    Parameters
    ----------
    faults : MachineFaults
        Validated faults.
    axis_names : sequence of str
        The axes, in the order of the positions.
    """

    def __init__(self, faults: MachineFaults, axis_names: Sequence[str]) -> None:
        names = list(axis_names)
        self._axes = tuple((k, 1.0 + a.scale_ppm * PER_PPM, a.cyclic_amplitude_um * M_PER_UM,
                            a.cyclic_pitch_mm * M_PER_MM)
                           for k, a in ((k, faults.axes.get(n)) for k, n in enumerate(names)) if a is not None)
        self._square = ((names.index(faults.squareness_axes[0]), names.index(faults.squareness_axes[1]),
                         faults.squareness_urad * RAD_PER_URAD) if faults.squareness_urad else None)

    def __call__(self, table_m: Sequence[float]) -> list[float]:
        """Tool positions [m] from the table positions [m] of one tick (after the play), one per axis."""
        tool = [float(v) for v in table_m]
        for k, scale, amplitude_m, pitch_m in self._axes:
            x = tool[k]
            tool[k] = x * scale + amplitude_m * math.sin(2.0 * math.pi * x / pitch_m)
        if self._square is not None:
            a, b, alpha_rad = self._square
            tool[a] = tool[a] + alpha_rad * tool[b]
        return tool


def apply_faults(table_m: npt.ArrayLike, faults: MachineFaults,
                 axis_names: Sequence[str]) -> npt.NDArray[np.float64]:
    """Tool positions from table positions (after the play), shape (n,) or (N, n), m (module docstring):
    :class:`ToolMap` on each row."""
    table = np.asarray(table_m, dtype=float)
    tool_map = ToolMap(faults, axis_names)
    rows = table.reshape(-1, table.shape[-1]).tolist()
    return np.array([tool_map(row) for row in rows], dtype=float).reshape(table.shape)


class FaultedPlant:
    """Any plant with machine faults on its tool side; everything but ``tool_positions_m`` is the inner plant's.

    Parameters
    ----------
    inner : Plant
        The plant model (motor side: what ``positions_m``/``state`` give the servo).
    faults : MachineFaults
        Validated faults; its axes must be the plant's.
    """

    def __init__(self, inner: Any, faults: MachineFaults) -> None:
        faults.check_axes(inner.axis_names)
        self.inner = inner
        self.faults = faults
        self.axis_names: tuple[str, ...] = tuple(inner.axis_names)
        self.command_unit: str = inner.command_unit
        self._backlash_m = [faults.axes[n].backlash_um * M_PER_UM if n in faults.axes else 0.0
                            for n in self.axis_names]
        self._table_m = list(inner.positions_m())
        self._gain = [1.0 + 0.01 * faults.axes[n].drive_gain_pct if n in faults.axes else 1.0
                      for n in self.axis_names]
        self._tool_map = ToolMap(faults, self.axis_names)
        self.positions_m, self.velocities_m_s, self.state = inner.positions_m, inner.velocities_m_s, inner.state
        self.forces_n = inner.forces_n

    def reset(self, positions_m: Sequence[float] | None = None) -> None:
        """The inner plant at rest at ``positions_m``; each table at its motor (middle of the dead band)."""
        self.inner.reset(positions_m)
        self._table_m = list(self.inner.positions_m())

    def step(self, commands: Sequence[float], dt_s: float) -> None:
        """The inner plant's step on the commands times the drive gains, then each table dragged through its
        dead band."""
        self.inner.step([c * g for c, g in zip(commands, self._gain)], dt_s)
        motor = self.inner.positions_m()
        self._table_m = [play(m, t, b) for m, t, b in zip(motor, self._table_m, self._backlash_m)]

    def tool_positions_m(self) -> npt.NDArray[np.float64]:
        """Tool positions, shape (n,), m: the tables with scale, cyclic and squareness errors."""
        return np.array(self._tool_map(self._table_m))

    def describe(self) -> dict[str, Any]:
        """The inner plant as drawn, with the faults."""
        return {**self.inner.describe(), "faults": config_values(self.faults)}


def tool_positions_m(plant: Any) -> npt.NDArray[np.float64]:
    """The tool positions of ``plant``, shape (n,), m: its ``tool_positions_m()``, else its positions."""
    tool = getattr(plant, "tool_positions_m", None)
    return tool() if tool is not None else plant.positions_m()
