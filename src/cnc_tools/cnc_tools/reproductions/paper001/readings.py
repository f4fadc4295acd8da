"""Which units make Table 1 and the PID gains 5/20/0.01 a working loop: the unit-reading study.

Paper 001 prints no units. A *reading* fixes the unit c carries in Eqs. 18-19
(the plant's ``mass_friction.length_unit``), the length unit the PID's error is
counted in (the servo's ``counts_per_m``) and the time base of the gains
(continuous, as the law takes them, or per sample). For each reading
:func:`reading_table` runs the two paper-001 scenarios with the PID alone on
the engine and reports, beside Tables 2 and 3:

- ε_peak [mm]: the largest exact contour error (the scorer's,
  :func:`~cnc_tools.analysis.scoring.contour_error_series`) over the scored
  run, and while the reference moves (``peak_motion_mm``);
- ε_ISE as Σε² over the 1 ms samples, ε in mm (so mm²), and two other ways
  the paper's number could have been formed, for the units check of the draft
  doc: ∫ε² dt in µm²·s and Σ|ε| in mm;
- whether every axis broke away from the static friction, how often an axis
  stuck again (``stops``), the largest tracking error, whether the loop
  diverged (a fault, a non-finite state or a contour error beyond
  :data:`DIVERGED_MM`);
- the closed-loop poles of the linear part (friction left out): the roots of
  ``m s³ + (B + K_d r) s² + K_p r s + K_i r`` per axis, r the PID's counts per
  plant length unit, and the spectral radius of the same loop sampled at T
  with a zero-order hold and the law's discrete PID (``scipy.signal``).

``python3 -m cnc_tools.reproductions.paper001.readings`` prints the table.
"""
from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import signal

from cnc_contour_control.axis.servo import NO_FERROR_TRIP
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.units import M_PER_MM, M_PER_UM
from cnc_contour_control.laws.pid import pid_gains_from_per_sample
from cnc_plant_sim.models.mass_friction import LENGTH_UNITS, MassFrictionAxisConfig, paper001_axes
from cnc_tools.analysis.scoring import contour_error_series, tracking_errors
from cnc_tools.analysis.tables import format_table
from cnc_tools.reproductions.paper001.data import SAMPLE_TIME_S, SCENARIOS, TABLE1_PID, paper_result
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import Scenario, load_scenario

#: A contour error beyond this [mm] (half the circle's radius) counts as diverged.
DIVERGED_MM = 5.0
#: Counts per metre of the PID's length unit.
COUNTS_PER_M = {"m": 1.0, "mm": 1.0 / M_PER_MM, "um": 1.0 / M_PER_UM}


@dataclass(frozen=True)
class Reading:
    """One unit reading of Table 1 and the gains.

    Attributes
    ----------
    name : str
        Short name.
    description : str
        For people.
    length_unit : str
        Unit of c in Eqs. 18-19 (``mass_friction.length_unit``).
    gain_unit : str
        Length unit of the PID's error (``counts_per_m`` = 1 / that unit in m).
    gains : Mapping
        ``kp``, ``ki`` [1/s], ``kd`` [s] as the law takes them.
    """

    name: str
    description: str
    length_unit: str
    gain_unit: str
    gains: Mapping[str, float] = field(default_factory=lambda: dict(TABLE1_PID))

    @property
    def counts_per_length_unit(self) -> float:
        """r: the PID's counts per plant length unit."""
        return COUNTS_PER_M[self.gain_unit] * LENGTH_UNITS[self.length_unit]

    def apply(self, scenario: Scenario) -> Scenario:
        """``scenario`` under this reading (plant length unit, counts per metre, gains), without the following-error
        trip: the study watches each reading's loop as it is (a stuck axis, a diverging loop), which the machine's
        default trip (2 mm + 0.5 s·|v|) would end at its first millimetres."""
        return scenario.variant({"plant": {"mass_friction": {"length_unit": self.length_unit}},
                                 "servo": {"counts_per_m": COUNTS_PER_M[self.gain_unit],
                                           "law_params": dict(self.gains), **NO_FERROR_TRIP}},
                                name=f"{scenario.name}_{self.name}")


_PER_SAMPLE = pid_gains_from_per_sample(**TABLE1_PID, sample_time_s=SAMPLE_TIME_S)

#: The readings studied, the reproduction's first.
READINGS: tuple[Reading, ...] = (
    Reading("mm_plant_um_gains", "c in mm (m = 0.45 N s²/mm = 450 kg), gains per µm (5 N/µm)", "mm", "um"),
    Reading("si", "consistent SI: c in m, gains per m (5 N/m)", "m", "m"),
    Reading("si_plant_mm_gains", "c in m (0.45 kg), gains per mm (5 N/mm)", "m", "mm"),
    Reading("si_plant_um_gains", "c in m (0.45 kg), gains per µm (5 N/µm)", "m", "um"),
    Reading("mm", "consistent mm: c in mm, gains per mm", "mm", "mm"),
    Reading("si_plant_mm_gains_per_sample", "c in m, gains per mm and per sample (Ki 20/T, Kd 0.01·T)",
            "m", "mm", _PER_SAMPLE),
)


def reading_named(name: str) -> Reading:
    """The reading of :data:`READINGS` called ``name``; ConfigError listing the valid names otherwise."""
    for reading in READINGS:
        if reading.name == name:
            return reading
    raise ConfigError(f"reading must be one of {[r.name for r in READINGS]}, got {name!r}")


def stable_readings(scenario: Scenario, readings: Sequence[Reading] = READINGS) -> tuple[Reading, ...]:
    """The readings whose sampled linear loop is stable on every axis of ``scenario``'s plant (|z| < 1).

    The loop of :func:`discrete_poles` (friction left out): a reading outside
    this set diverges or never settles whatever a compensator learns.
    """
    stable = []
    for reading in readings:
        plant = reading.apply(scenario).plant
        radius = max(float(np.max(np.abs(discrete_poles(axis, reading, scenario.sample_time_s))))
                     for axis in paper001_axes(plant.axes, plant.axis_overrides))
        if radius < 1.0:
            stable.append(reading)
    return tuple(stable)


# --------------------------------------------------------------------------- the linear loop


def continuous_poles(axis: MassFrictionAxisConfig, reading: Reading) -> np.ndarray:
    """Roots of ``m s³ + (B + K_d r) s² + K_p r s + K_i r`` [1/s]: the PID around m s² + B s."""
    r, g = reading.counts_per_length_unit, reading.gains
    return np.roots([axis.mass, axis.viscous + g["kd"] * r, g["kp"] * r, g["ki"] * r])


def discrete_poles(axis: MassFrictionAxisConfig, reading: Reading, sample_time_s: float) -> np.ndarray:
    """Closed-loop poles in z of the ZOH-sampled ``r/(m s² + B s)`` under the law's discrete PID.

    The law (velocity form) is ``C(z) = K_p + K_i T z/(z − 1) + (K_d/T)(z − 1)/z``.
    """
    r, g, t = reading.counts_per_length_unit, reading.gains, sample_time_s
    num, den, _ = signal.cont2discrete(([r], [axis.mass, axis.viscous, 0.0]), t, method="zoh")
    c_num = np.polyadd(np.polyadd(g["kp"] * np.array([1.0, -1.0, 0.0]), g["ki"] * t * np.array([1.0, 0.0, 0.0])),
                       g["kd"] / t * np.array([1.0, -2.0, 1.0]))
    c_den = np.array([1.0, -1.0, 0.0])
    return np.roots(np.polyadd(np.polymul(c_den, den), np.polymul(c_num, np.ravel(num))))


# --------------------------------------------------------------------------- one run


def measure(record: RunRecord, sample_time_s: float) -> dict[str, Any]:
    """ε_peak, the ISE variants, break-away, stops and divergence of one recorded run."""
    series, _ = contour_error_series(record)
    error_mm = series.error_m / M_PER_MM
    _, tracking_m = tracking_errors(record)
    tracking_mm = float(np.max(np.abs(tracking_m))) / M_PER_MM if tracking_m.size else math.nan
    velocity = record.joint_states.velocity_m_s
    in_motion = _while_moving(record, series.stamp_ns)
    return {
        "peak_mm": float(error_mm.max()),
        "peak_motion_mm": float(error_mm[in_motion].max()) if in_motion.any() else math.nan,
        "ise_mm2": float(np.sum(error_mm ** 2)),
        "ise_um2_s": float(np.sum((series.error_m / M_PER_UM) ** 2) * sample_time_s),
        "iae_mm": float(np.sum(error_mm)),
        "samples": int(error_mm.size),
        "tracking_max_mm": tracking_mm,
        "broke_away": bool(np.all(np.any(velocity != 0.0, axis=0))),
        "stops": _stops(velocity),
        "diverged": not np.all(np.isfinite(record.joint_states.position_m)) or float(error_mm.max()) > DIVERGED_MM,
    }


def _while_moving(record: RunRecord, stamps_ns: np.ndarray) -> np.ndarray:
    """Which of ``stamps_ns`` fall where the reference moves (feed > 0); all of them without a reference."""
    if record.reference is None:
        return np.ones(stamps_ns.shape, bool)
    return np.isin(stamps_ns, record.reference.stamp_ns[record.reference.feed_m_s > 0.0])


def _stops(velocity: np.ndarray) -> int:
    """How often an axis went from moving to exactly at rest (sticking again), all axes."""
    at_rest = velocity == 0.0
    return int(np.sum(at_rest[1:] & ~at_rest[:-1]))


def run_reading(scenario: Scenario, reading: Reading) -> dict[str, Any]:
    """Run ``scenario`` under ``reading`` on the engine and measure it (a fault counts as diverged)."""
    try:
        return measure(run_engine(reading.apply(scenario)), scenario.sample_time_s)
    except FaultError as err:
        return {"peak_mm": math.nan, "ise_mm2": math.nan, "diverged": True, "fault": str(err)}


# --------------------------------------------------------------------------- the table


def reading_table(readings: Sequence[Reading] = READINGS,
                  scenarios: Mapping[str, Scenario] | None = None) -> list[dict[str, Any]]:
    """One row per reading and contour: ours beside Tables 2 and 3, and the linear loop's poles."""
    scenarios = dict(scenarios) if scenarios is not None else default_scenarios()
    rows = []
    for reading in readings:
        loop = _loop(reading, next(iter(scenarios.values())))
        for contour, scenario in scenarios.items():
            paper = paper_result(contour)
            rows.append({"reading": reading.name, "description": reading.description, "contour": contour,
                         "length_unit": reading.length_unit, "gain_unit": reading.gain_unit,
                         "gains": dict(reading.gains), "paper_peak_mm": paper.peak_mm, "paper_ise": paper.ise,
                         **run_reading(scenario, reading), **loop})
    return rows


def default_scenarios() -> dict[str, Scenario]:
    """The paper-001 scenarios by contour, from the project's ``scenarios/``."""
    return {contour: load_scenario(project_root() / path) for contour, path in SCENARIOS.items()}


def _loop(reading: Reading, scenario: Scenario) -> dict[str, Any]:
    """Per axis: the continuous poles (rounded) and the largest real part; the discrete spectral radius."""
    plant = reading.apply(scenario).plant
    configs = paper001_axes(plant.axes, plant.axis_overrides)
    poles = {c.name: continuous_poles(c, reading) for c in configs}
    radius = max(float(np.max(np.abs(discrete_poles(c, reading, scenario.sample_time_s)))) for c in configs)
    return {"poles": {name: [complex(round(p.real, 2), round(p.imag, 2)) for p in value]
                      for name, value in poles.items()},
            "max_real_pole": max(float(np.max(p.real)) for p in poles.values()),
            "spectral_radius": radius}


# --------------------------------------------------------------------------- printing


#: Columns of the printed table: header and the row's value (the paper's numbers as printed, ISE to 4
#: significant digits, |z| to 4 places: 1.0013 must not read as 1).
COLUMNS: tuple[tuple[str, Any], ...] = (
    ("reading", lambda r: r["reading"]), ("contour", lambda r: r["contour"]),
    ("peak mm", lambda r: r["peak_mm"]), ("paper", lambda r: f"{r['paper_peak_mm']:.4f}"),
    ("x paper", lambda r: r["peak_mm"] / r["paper_peak_mm"]),
    ("moving mm", lambda r: r.get("peak_motion_mm", math.nan)),
    ("ISE mm2", lambda r: f"{r['ise_mm2']:.4g}"), ("paper", lambda r: f"{r['paper_ise']:.4f}"),
    ("track mm", lambda r: r.get("tracking_max_mm", math.nan)), ("moved", lambda r: str(r.get("broke_away", "-"))),
    ("stops", lambda r: r.get("stops", -1)), ("diverged", lambda r: str(r["diverged"])),
    ("max Re s", lambda r: r["max_real_pole"]), ("|z| max", lambda r: f"{r['spectral_radius']:.4f}"),
)


def table_text(rows: Sequence[Mapping[str, Any]]) -> str:
    """The rows as an aligned table: ours beside the paper's PID column."""
    return format_table([name for name, _ in COLUMNS], [[cell(r) for _, cell in COLUMNS] for r in rows])


def main() -> None:
    """Print the reading table with the 1-min load it ran under."""
    rows = reading_table()
    print(table_text(rows))
    print(f"(engine, T = {SAMPLE_TIME_S * 1e3:g} ms; ISE = Σε² over the samples, ε in mm; "
          f"1-min load {os.getloadavg()[0]:.2f})")


if __name__ == "__main__":
    main()
