"""The friction–velocity curve of paper 000's identification: per-speed summaries, the quadratic fit per
direction and the fitted table (the runs and points are in :mod:`cnc_tools.identification.friction`)."""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from cnc_contour_control.core.errors import ConfigError
from cnc_plant_sim.models.friction import TableFriction
from cnc_plant_sim.models.friction import table as table_friction
from cnc_tools.identification.friction import FloatArray, FrictionPoint


# =========================================================================== the curve
@dataclass(frozen=True)
class SpeedSummary:
    """All plants at one signed speed: the nominal point and the run-to-run band of the varied plants."""

    velocity_mm_s: float
    nominal: FrictionPoint
    varied: tuple[FrictionPoint, ...]

    def _steady(self) -> FloatArray:
        return np.array([p.friction_dac for p in self.varied if p.status == "steady"])

    @property
    def band_dac(self) -> tuple[float, float, float, float]:
        """(mean, std, min, max) of the steady varied plants' ``friction_dac`` (NaN without any)."""
        values = self._steady()
        if values.size == 0:
            return (math.nan,) * 4
        return float(values.mean()), float(values.std()), float(values.min()), float(values.max())

    @property
    def half_range_dac(self) -> float:
        """Half the min–max range of the varied plants (NaN with fewer than two)."""
        values = self._steady()
        return float(np.ptp(values)) / 2.0 if values.size > 1 else math.nan


def summarise(points: Sequence[FrictionPoint]) -> list[SpeedSummary]:
    """Group the points by signed speed (ascending); every speed needs its nominal point."""
    by_speed: dict[float, list[FrictionPoint]] = {}
    for point in points:
        by_speed.setdefault(point.velocity_mm_s, []).append(point)
    summaries = []
    for speed in sorted(by_speed):
        group = by_speed[speed]
        nominal = [p for p in group if p.seed is None]
        if len(nominal) != 1:
            raise ConfigError(f"speed {speed:+g} mm/s needs exactly one nominal point, got {len(nominal)}")
        summaries.append(SpeedSummary(speed, nominal[0], tuple(p for p in group if p.seed is not None)))
    return summaries


@dataclass(frozen=True)
class BranchFit:
    """One branch of the fitted curve in the form of Eq. (15).

    ``coefficients_dac`` = (c2, c1, c0) of ``c2 V² + c1 V + c0`` for
    ``|V| < limit_speed_mm_s``; ``high_dac`` beyond (None: the quadratic throughout).
    ``direction`` is +1 (V > 0) or −1; ``rms_dac`` the fit residual.
    """

    direction: int
    coefficients_dac: tuple[float, float, float]
    limit_speed_mm_s: float
    high_dac: float | None
    rms_dac: float

    def force(self, velocity_mm_s: FloatArray | float) -> FloatArray:
        """Fitted force [DAC] at velocities of this branch's sign [mm/s]."""
        v = np.asarray(velocity_mm_s, dtype=float)
        quadratic = np.polyval(self.coefficients_dac, v)
        if self.high_dac is None:
            return quadratic
        return np.where(np.abs(v) < self.limit_speed_mm_s, quadratic, self.high_dac)


def fit_branch(velocity_mm_s: Sequence[float], force_dac: Sequence[float]) -> BranchFit:
    """Least-squares quadratic + constant on one branch; the break is tried between every pair of speeds.

    Needs at least 3 points, all of one sign. The constant part needs 2 points;
    with fewer the quadratic covers the whole branch.
    """
    v, f = np.asarray(velocity_mm_s, dtype=float), np.asarray(force_dac, dtype=float)
    order = np.argsort(np.abs(v))
    v, f = v[order], f[order]
    if v.size < 3 or not (np.all(v > 0) or np.all(v < 0)):
        raise ConfigError(f"a branch fit needs >= 3 steady speeds of one sign, got {v.tolist()}")
    direction = 1 if v[0] > 0 else -1
    best = _fit_quadratic(v, f, direction, math.inf, None)
    for split in range(3, v.size - 1):
        high = float(f[split:].mean())
        limit = float(abs(v[split - 1] + v[split]) / 2.0)
        candidate = _fit_quadratic(v[:split], f[:split], direction, limit, high, v[split:], f[split:])
        if candidate.rms_dac < best.rms_dac - 1e-9:
            best = candidate
    return best


def _fit_quadratic(v: FloatArray, f: FloatArray, direction: int, limit: float, high: float | None,
                   v_high: FloatArray | None = None, f_high: FloatArray | None = None) -> BranchFit:
    coefficients = np.polyfit(v, f, 2)
    tail = [] if f_high is None else f_high - high  # type: ignore[operator]  # high is given with f_high
    residual = np.concatenate([np.polyval(coefficients, v) - f, tail])
    n_points = v.size + (0 if v_high is None else v_high.size)
    rms = float(np.sqrt(np.sum(residual ** 2) / n_points))
    return BranchFit(direction, tuple(float(c) for c in coefficients), limit, high, rms)  # type: ignore[arg-type]  # degree 2: 3 values


def fit_curve(points: Sequence[FrictionPoint]) -> tuple[BranchFit, BranchFit]:
    """(positive, negative) branch fits of the steady points given (e.g. the nominal plant's)."""
    steady = [p for p in points if p.status == "steady"]
    fits = []
    for sign in (1, -1):
        branch = [p for p in steady if p.velocity_mm_s * sign > 0]
        fits.append(fit_branch([p.velocity_mm_s for p in branch], [p.friction_dac for p in branch]))
    return fits[0], fits[1]


#: Spacing of the table's samples of the fitted quadratic [mm/s] (linear interpolation error < 0.01 DAC).
TABLE_STEP_MM_S = 0.5
#: The table's innermost speed [mm/s]: below it a branch holds its value; V = 0 takes the breakaway level.
TABLE_INNER_MM_S = 0.01


def _branch_samples(fit: BranchFit, max_speed_mm_s: float) -> tuple[FloatArray, FloatArray]:
    end = min(fit.limit_speed_mm_s, max_speed_mm_s)
    speeds = np.unique(np.r_[TABLE_INNER_MM_S, np.arange(TABLE_STEP_MM_S, end, TABLE_STEP_MM_S), end - 1e-3])
    if fit.high_dac is not None and fit.limit_speed_mm_s < max_speed_mm_s:
        speeds = np.r_[speeds, fit.limit_speed_mm_s]
    velocity = fit.direction * speeds
    return velocity, fit.force(velocity)


def fitted_table(fits: tuple[BranchFit, BranchFit], max_speed_mm_s: float) -> TableFriction:
    """The fitted curve sampled into a ``table`` friction; breakaway levels are the quadratics at V = 0."""
    pos_v, pos_f = _branch_samples(fits[0], max_speed_mm_s)
    neg_v, neg_f = _branch_samples(fits[1], max_speed_mm_s)
    return TableFriction.from_arrays(np.round(np.r_[neg_v, pos_v], 6), np.round(np.r_[neg_f, pos_f], 4),
                                     breakaway_positive_dac=round(fits[0].coefficients_dac[2], 4),
                                     breakaway_negative_dac=round(fits[1].coefficients_dac[2], 4))


TABLE_HEADER = """\
# Friction table identified by `cnc-contour identify-friction` (paper 000, Section 2, Eq. 1a).
# Force in DAC units against velocity in mm/s, linear interpolation between points, each
# branch constant beyond its ends; V = 0 exactly takes the breakaway level of the branch.
# As a plant friction model:  plant: {axis_overrides: {<axis>: {friction: table, friction_params: <friction_params>}}}
# As a feedforward table:     u_ff(k) = F(v_ref(k)) with v_ref in mm/s (cnc_tools.identification.friction.load_table)
"""


def table_document(table: TableFriction, fits: tuple[BranchFit, BranchFit], meta: Mapping[str, Any]) -> dict[str, Any]:
    """The YAML document of a friction table (``friction``, ``friction_params``, ``fit``, ``identification``)."""
    return {"axis": meta.get("axis"), "friction": "table", "friction_params": table.to_params(),
            "fit": {name: {"coefficients_dac": [round(c, 5) for c in fit.coefficients_dac],
                           "limit_speed_mm_s": None if math.isinf(fit.limit_speed_mm_s) else fit.limit_speed_mm_s,
                           "high_dac": None if fit.high_dac is None else round(fit.high_dac, 4),
                           "rms_dac": round(fit.rms_dac, 4)}
                    for name, fit in (("positive", fits[0]), ("negative", fits[1]))},
            "identification": dict(meta)}


def write_table(path: Path, table: TableFriction, fits: tuple[BranchFit, BranchFit], meta: Mapping[str, Any]) -> Path:
    """Write the table YAML (see :data:`TABLE_HEADER` for the format); the folder is created."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(TABLE_HEADER + yaml.safe_dump(table_document(table, fits, meta), sort_keys=False,
                                                      default_flow_style=None, width=100))
    return path


def load_table(path: Path) -> TableFriction:
    """Read a table YAML written by :func:`write_table` back as a friction model."""
    try:
        document = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as err:
        raise ConfigError(f"friction table {str(path)!r} cannot be read: {err}") from err
    if not isinstance(document, Mapping) or document.get("friction") != "table":
        raise ConfigError(f"friction table {str(path)!r} must be a mapping with friction: table")
    return table_friction(document.get("friction_params"))

