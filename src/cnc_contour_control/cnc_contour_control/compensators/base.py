"""The compensator seam: what a compensator sees each tick, the protocol it keeps, and the input check.

A compensator adds one correction per axis, in the drive's command unit, to
each servo's command (stage 4 of the tick, DESIGN §10)::

    sample:  tick, dt_s, ref_position_m[i], position_m[i], contour_error_m,
             angle_rad, tracking_error_m[i]
    output:  correction[i]  (drive units; the servo adds it to its law's output)

**Sign of the contour error** (fixed by ``ContourError.msg``; the estimator
uses it): ``contour_error_m`` ε_c > 0 when the actual position P lies to the
LEFT of the direction of travel θ (``angle_rad``): ε_c = (P − P_line)·n with
the left normal n = (−sin θ, cos θ) in the plane of the first two axes. So

    ∂ε_c/∂c_x = −sin θ,   ∂ε_c/∂c_y = cos θ,

and a correction along −n (to the right) reduces a positive ε_c when each
axis's drive moves its axis in the direction of a positive command. Axes
beyond the first two are not in the contour plane: their ∂ε_c/∂c is taken 0.

The sample is a mutable slots object: the caller fills one and passes it
every tick (nothing is built per tick). :func:`check_sample` refuses a
non-finite value or a wrong length naming the field and the axis, before a
compensator's state sees it.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

from cnc_contour_control.compensators.state_file import load_state, save_state
from cnc_contour_control.core.config import require_finite
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.core.slots import SlotsRecord

_AXIS_FIELDS = ("ref_position_m", "position_m", "tracking_error_m")


class CompensatorSample(SlotsRecord):
    """One tick as a compensator sees it (SI; axis order of the compensator's ``axis_names``).

    Attributes
    ----------
    tick : int
        Tick index in the run, 0 at the run's first tick.
    dt_s : float
        Period since the previous tick [s], > 0.
    ref_position_m : list of float, shape (n,)
        Reference position per axis [m].
    position_m : list of float, shape (n,)
        Measured position per axis [m].
    contour_error_m : float
        Signed contour error from the estimator [m], > 0 to the left of travel.
    angle_rad : float
        Direction of travel (local tangent) in the plane of the first two axes [rad].
    tracking_error_m : list of float, shape (n,)
        Following error ``reference − position`` per axis [m].
    """

    __slots__ = ("tick", "dt_s", "ref_position_m", "position_m", "contour_error_m", "angle_rad",
                 "tracking_error_m")

    def __init__(self, axis_count: int = 2, dt_s: float = 0.001) -> None:
        self.tick = 0
        self.dt_s = dt_s
        self.ref_position_m = [0.0] * axis_count
        self.position_m = [0.0] * axis_count
        self.contour_error_m = 0.0
        self.angle_rad = 0.0
        self.tracking_error_m = [0.0] * axis_count



def check_sample(who: str, sample: CompensatorSample, axis_names: Sequence[str]) -> None:
    """Raise :class:`FaultError` naming ``who``, the field and the axis of a bad value in ``sample``.

    Refused: a per-axis list of the wrong length, a non-finite value, ``dt_s <= 0``,
    a negative tick. The common case (all finite) costs one sum.
    """
    n = len(axis_names)
    refs, positions, errors = sample.ref_position_m, sample.position_m, sample.tracking_error_m
    if len(refs) == n and len(positions) == n and len(errors) == n:
        total = sample.dt_s + sample.contour_error_m + sample.angle_rad + sum(refs) + sum(positions) + sum(errors)
        if total - total == 0.0 and sample.dt_s > 0.0 and sample.tick >= 0:
            return
    _explain(who, sample, axis_names)


def _explain(who: str, sample: CompensatorSample, axis_names: Sequence[str]) -> None:
    """The first problem of ``sample`` as a FaultError (called only when the fast check failed)."""
    for name in _AXIS_FIELDS:
        values = getattr(sample, name)
        if len(values) != len(axis_names):
            raise FaultError(f"{who}: {name} must have {len(axis_names)} values (axes {list(axis_names)}), "
                             f"got {len(values)}")
        for axis, value in zip(axis_names, values):
            if not math.isfinite(value):
                raise FaultError(f"{who}: {name}[{axis}] must be finite, got {value!r}")
    for name in ("dt_s", "contour_error_m", "angle_rad"):
        if not math.isfinite(getattr(sample, name)):
            raise FaultError(f"{who}: {name} must be finite, got {getattr(sample, name)!r}")
    if not sample.dt_s > 0.0:
        raise FaultError(f"{who}: dt_s must be > 0, got {sample.dt_s!r}")
    if sample.tick < 0:
        raise FaultError(f"{who}: tick must be >= 0, got {sample.tick!r}")
    raise FaultError(f"{who}: the sample's values overflow when summed ({sample!r})")


def checked_factors(name: str, value: object, context: str) -> tuple[float, ...]:
    """``value`` as a tuple of finite floats (a config's per-axis list), or a ConfigError naming the entry."""
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise ConfigError(f"{context}.{name} must be a list of numbers, got {value!r}")
    return tuple(require_finite(f"{name}[{k}]", v, context) for k, v in enumerate(value))


def factors_for(name: str, factors: tuple[float, ...], axis_names: Sequence[str], context: str) -> tuple[float, ...]:
    """One factor per axis: ``factors`` if it has one per axis, 1 on every axis if it is empty."""
    if not factors:
        return (1.0,) * len(axis_names)
    if len(factors) != len(axis_names):
        raise ConfigError(f"{context}.{name} must have one value per axis {list(axis_names)}, got {list(factors)}")
    return factors


@runtime_checkable
class Compensator(Protocol):
    """A per-tick cross-axis correction, possibly learning within a run or from run to run.

    Attributes
    ----------
    axis_names : tuple of str
        The axes, in the order of every per-axis list.
    frozen : bool
        True: learning off, the output still applied.
    fault : str or None
        Why a guard stopped the compensator (it then outputs zeros), else None.
    """

    axis_names: tuple[str, ...]
    frozen: bool
    fault: str | None

    def reset(self) -> None:
        """Start of a run: clear the per-run signals, keep what was learned."""

    def step(self, sample: CompensatorSample) -> list[float]:
        """One tick: a correction per axis [drive units]; a bad sample raises FaultError, state untouched."""

    def end_run(self) -> None:
        """After the run's last tick: a run-to-run learner updates here (a no-op for others)."""

    def save(self, path: str | Path) -> None:
        """Write what was learned to the ``.npz`` file ``path``."""

    def load(self, path: str | Path) -> None:
        """Read what was learned from ``path`` (refused naming the file and the problem)."""


@dataclass(frozen=True)
class NoCompensatorConfig:
    """The ``none`` compensator has no parameters."""

    def __post_init__(self) -> None:
        check_ranges(self, "none")


class ZeroCompensator:
    """The ``none`` compensator: zeros on every axis; checks its input like the others; nothing to learn.

    ``save`` writes an empty ``.npz``; ``load`` accepts only an empty one.
    """

    def __init__(self, config: NoCompensatorConfig, axis_names: Sequence[str]) -> None:
        self.config = config
        self.axis_names = tuple(axis_names)
        self.frozen = False
        self.fault: str | None = None
        self._zeros = [0.0] * len(self.axis_names)

    def reset(self) -> None:
        """Nothing to clear."""

    def step(self, sample: CompensatorSample) -> list[float]:
        """Zeros (a fresh list) after the input check."""
        check_sample("none compensator", sample, self.axis_names)
        return self._zeros[:]

    def end_run(self) -> None:
        """Nothing to learn."""

    def save(self, path: str | Path) -> None:
        """Write an empty state file."""
        save_state(path, {})

    def load(self, path: str | Path) -> None:
        """Check ``path`` is a numeric ``.npz`` without arrays."""
        load_state(path, {}, "none compensator state")


#: Largest gain or limit a compensator config accepts.
MAX_GAIN = 1.0e12


@dataclass(frozen=True)
class AxisCorrection:
    """The fields of a compensator whose one correction is spread over the axes (CCC, ILC).

    Parameters
    ----------
    axis_gains : tuple of float
        Factor on each axis's correction, finite; empty: 1 on every axis.
    output_limit : float
        Clip of each correction [drive units], in [1e-9, 1e12].
    """

    axis_gains: tuple[float, ...] = param((), description="factor on each axis's correction (empty: all 1)")
    output_limit: float = param(100.0, unit="drive", low=1.0e-9, high=MAX_GAIN, description="clip of each correction")

    def check(self, context: str) -> None:
        """Validate every declared range and the axis factors (call from the subclass's ``__post_init__``)."""
        check_ranges(self, context)
        object.__setattr__(self, "axis_gains", checked_factors("axis_gains", self.axis_gains, context))
