"""Error metrics, chosen by name from a registry.

A metric maps an error signal ``error_m`` (N,) and its sample weights
``weight_s`` (N,) (trapezoid-rule time weights, s) to one number in SI units:
m for ``max``, ``rms`` and ``mean_abs``, m²·s for ``ise``. ``Metric.convert``
turns that into µm or BLU (µm²·s, BLU²·s for the integral).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cnc_contour_control.core.config import require_choice, require_positive
from cnc_contour_control.core.units import M_PER_BLU_PAPER000, M_PER_UM

FloatArray = NDArray[np.float64]

#: Length units of reports: label for people, key suffix for machines.
UNIT_LABELS: dict[str, str] = {"um": "µm", "blu": "BLU"}


@dataclass(frozen=True)
class Metric:
    """One error metric.

    Attributes
    ----------
    name
        Registry key, e.g. ``"rms"``.
    description
        What it computes, for tables and ``--help``.
    length_power
        The value scales as length**length_power (1: m, 2: m²·s).
    per_second
        True when the value is an integral over time (unit carries ·s).
    compute
        ``(error_m (N,), weight_s (N,)) -> value`` in SI; NaN for an empty signal.
    """

    name: str
    description: str
    length_power: int
    per_second: bool
    compute: Callable[[FloatArray, FloatArray], float]

    def convert(self, value_si: float, m_per_unit: float) -> float:
        """The SI value expressed in a length unit of ``m_per_unit`` metres."""
        return value_si / m_per_unit ** self.length_power

    def unit_key(self, unit: str) -> str:
        """Machine-readable unit suffix: ``um``, ``um2_s``, ``blu``, ``blu2_s``."""
        power = "" if self.length_power == 1 else str(self.length_power)
        return f"{unit}{power}{'_s' if self.per_second else ''}"

    def unit_label(self, unit: str) -> str:
        """Unit for people: ``µm``, ``µm²·s``, ``BLU``, ``BLU²·s``."""
        power = {1: "", 2: "²", 3: "³"}[self.length_power]
        return f"{UNIT_LABELS[unit]}{power}{'·s' if self.per_second else ''}"


def _empty_guard(compute: Callable[[FloatArray, FloatArray], float]) -> Callable[[FloatArray, FloatArray], float]:
    def guarded(error_m: FloatArray, weight_s: FloatArray) -> float:
        return math.nan if np.size(error_m) == 0 else float(compute(np.asarray(error_m), np.asarray(weight_s)))
    return guarded


METRICS: dict[str, Metric] = {
    metric.name: metric for metric in (
        Metric("max", "largest |error|", 1, False, _empty_guard(lambda e, w: np.max(np.abs(e)))),
        Metric("rms", "root mean square of the samples", 1, False,
               _empty_guard(lambda e, w: np.sqrt(np.mean(np.square(e))))),
        Metric("mean_abs", "mean |error| of the samples", 1, False,
               _empty_guard(lambda e, w: float(np.mean(np.abs(e))))),
        Metric("ise", "integral of error² over time (trapezoid rule)", 2, True,
               _empty_guard(lambda e, w: np.sum(np.square(e) * w))),
    )
}
#: Metrics of a score when none are named.
DEFAULT_METRICS: tuple[str, ...] = ("max", "rms", "mean_abs", "ise")


def get_metrics(names: Sequence[str] | None = None) -> tuple[Metric, ...]:
    """Metrics by name (default ``DEFAULT_METRICS``); an unknown name raises ``ConfigError`` listing the valid ones."""
    chosen = DEFAULT_METRICS if names is None else tuple(names)
    return tuple(METRICS[require_choice("metrics", name, METRICS)] for name in chosen)


def length_units(blu_m: float = M_PER_BLU_PAPER000) -> dict[str, float]:
    """Report length units in metres: ``{"um": 1e-6, "blu": blu_m}``."""
    return {"um": M_PER_UM, "blu": require_positive("blu_m", blu_m)}


def trapezoid_weights_s(stamp_s: FloatArray) -> FloatArray:
    """Time weights (N,) s such that ``sum(f * w)`` is the trapezoid integral of samples ``f`` at ``stamp_s`` (N,)."""
    t = np.asarray(stamp_s, dtype=float)
    weight = np.zeros_like(t)
    if t.size > 1:
        step = np.diff(t)
        weight[:-1] += 0.5 * step
        weight[1:] += 0.5 * step
    return weight


def evaluate(metrics: Sequence[Metric], error_m: FloatArray, weight_s: FloatArray) -> dict[str, float]:
    """SI value of every metric on one signal: ``{name: value}``."""
    return {metric.name: metric.compute(error_m, weight_s) for metric in metrics}
