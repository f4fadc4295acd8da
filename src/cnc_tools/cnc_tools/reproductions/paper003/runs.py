"""Paper 003's tests simulated on the paper-003 plant: the circular-test grid, the feed step, the grid objective.

**Circles.** Each circle of the grid is a lead-in of ``ω·LEAD_IN_S`` (``ω = F/R``;
full turns, then the rest, as arcs) followed by one full turn at the programmed
feed; only the full turn is measured (its samples: the stamps where the
reference is on the last segment and not done), so the start-up transient of
the position loop, the velocity loop and the acceleration/deceleration filter
is left out, as a ballbar's lead-in arc leaves it out. The acceleration limit is raised to
:data:`GRID_ACCELERATION_MM_S2` so no circle of the grid is slowed (8000 mm/min
on R = 1.5 mm needs F²/R = 11.9 m/s²). Per circle: the radius reduction
``−mean(|p − c| − R)`` (the paper's "radius-reduction error", steady), and
the largest ``| |p − c| − R |`` over the turn.

**The linear prediction** of a circle (:func:`predicted_radius_gain`): with equal
axes and no friction the plant is linear and isotropic, so a circle of radius R
at ``ω`` comes out a circle of radius ``R |G(jω)|``,
``G(s) = H(s) (k + f s) / (s + k H(s) e^{-sT/2}) · 1/(1 + T_ip s)`` (H: Eq. 1; k the
position gain; f the velocity feedforward ``ff1``; T the sample period: the
servo answers tick k's position with a command held over [k, k+1], a
zero-order hold, whose mean delay is T/2; T_ip the exponential
acceleration/deceleration). The simulation agrees with it to 0.01 % without
feedforward and within 0.35 µm with it (test); a delay of 0 or T is 1-3 % off.

**Rise time** (:func:`measure_rise_time_s`): a line along x at 1000 mm/min started
as a step (no acceleration/deceleration, acceleration limit
:data:`STEP_ACCELERATION_MM_S2`); the 10-90 % rise of the x velocity.

Work items are plain picklable values and :func:`measure_circle` a module-level
function, so a grid runs through any :mod:`cnc_tools.runs.executor` executor.
"""
from __future__ import annotations

import cmath
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cnc_contour_control.core.errors import CncError, ConfigError
from cnc_tools.analysis.ballbar_trace import measured_positions
from cnc_tools.reproductions.paper003 import data
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.executor import Executor
from cnc_tools.runs.scenario import Scenario
from cnc_tools.tuning import paper003_model as p3
from cnc_tools.tuning.problem import DesignVariable, overrides_of

#: Time of the lead-in arc before the measured turn [s] (>= 12 time constants 1/k at k = 30 /s).
LEAD_IN_S = 0.4
#: Acceleration limit of the grid's runs [mm/s²]: 4x the grid's largest centripetal need (8000 mm/min, R 1.5 mm).
GRID_ACCELERATION_MM_S2 = 50000.0
#: Acceleration limit of the feed step [mm/s²]: the feed is reached within one 1 ms sample.
STEP_ACCELERATION_MM_S2 = 1.0e7
#: Length of the feed-step line [mm] and the time after the step that is kept [s].
STEP_LENGTH_MM = 10.0
#: Settle after the program [s] (the measured samples end where the reference is done).
SETTLE_S = 0.02
MM_PER_M = 1000.0
UM_PER_M = 1.0e6


@dataclass(frozen=True)
class GridCircle:
    """One circular test: feed [mm/min], radius [mm], direction (cw, ccw)."""

    feed_mm_min: float
    radius_mm: float
    direction: str

    @property
    def omega_rad_s(self) -> float:
        """Angular speed F/R [rad/s]."""
        return self.feed_mm_min / 60.0 / self.radius_mm

    @property
    def label(self) -> str:
        """``F1000 R1.5 cw``."""
        return f"F{self.feed_mm_min:g} R{self.radius_mm:g} {self.direction}"


def grid(feeds_mm_min: Sequence[float] = data.GRID_FEEDS_MM_MIN, radii_mm: Sequence[float] = data.GRID_RADII_MM,
         directions: Sequence[str] = data.GRID_DIRECTIONS) -> tuple[GridCircle, ...]:
    """The circles of the grid (feed-major, then radius, then direction)."""
    return tuple(GridCircle(f, r, d) for f in feeds_mm_min for r in radii_mm for d in directions)


@dataclass(frozen=True)
class Setting:
    """One gain setting of the drive: K1, K2 (Eq. 1), position gain k [1/s], velocity feedforward ff1 [-]."""

    name: str
    k1: float
    k2: float
    position_gain_1_s: float
    ff1: float = 0.0

    def model(self, base: p3.Paper003Model) -> p3.Paper003Model:
        """The paper-003 linear model of this setting (T, T_ip, K_t/J_m from ``base``)."""
        return base.with_(k1=self.k1, k2=self.k2, position_gain_x_1_s=self.position_gain_1_s,
                          position_gain_y_1_s=self.position_gain_1_s)

    def overrides(self, axes: Sequence[str]) -> dict[str, Any]:
        """The scenario keys of this setting (the same keys the tuner's design variables name)."""
        return overrides_of(SETTING_VARIABLES, (self.k1, self.k2, self.position_gain_1_s, self.ff1), axes)


#: The scenario keys of a :class:`Setting`, in its field order (bounds: the tuning box of the bench).
SETTING_VARIABLES: tuple[DesignVariable, ...] = (
    DesignVariable("plant.axis_overrides.*.ki", 10.0, 200.0),     # K1
    DesignVariable("plant.axis_overrides.*.kp", 0.1, 5.0),        # K2
    DesignVariable("servo.law_params.kp", 10.0, 300.0),           # position gain k [1/s]
    DesignVariable("servo.ff1", 0.0, 1.0),                        # velocity feedforward (1: all of the reference's)
)


def column_setting(column: str, position_gain_1_s: float) -> Setting:
    """A Table 2 column's K1, K2 at position gain ``position_gain_1_s``, no feedforward (the paper has none)."""
    row = data.PAPER003_TABLE[column]
    return Setting(column, row.k1, row.k2, position_gain_1_s)


def setting_at(name: str, x: Sequence[float] | np.ndarray) -> Setting:
    """The :class:`Setting` at a point of :data:`SETTING_VARIABLES`."""
    return Setting(name, *(float(v) for v in x))


def model_of_scenario(scenario: Scenario) -> p3.Paper003Model:
    """T, T_ip and the standard gains of the scenario as a paper-003 model (interpolation must be exponential)."""
    kind = scenario.raw.get("interpolator", {}).get("accel_decel", {}).get("kind", "none")
    if kind not in ("exponential", "none"):
        raise ConfigError(f"interpolator.accel_decel.kind must be exponential or none for the paper003 bench, "
                          f"got {kind!r}")
    t_ip_s = scenario.raw["interpolator"]["accel_decel"]["time_constant_s"] if kind == "exponential" else 0.0
    return p3.Paper003Model(t_ip_s=float(t_ip_s), sample_time_s=float(scenario.raw["sample_time_s"]))


def _point_mm(radius_mm: float, angle_rad: float) -> list[float]:
    """A point of the circle centred at (0, R) (the start (0, 0) is at -90°)."""
    return [radius_mm * math.cos(angle_rad), radius_mm + radius_mm * math.sin(angle_rad)]


def circle_program(circle: GridCircle) -> dict[str, Any]:
    """Lead-in arcs of ``ω·LEAD_IN_S`` in all (full turns, then the rest), then the measured full turn.

    Centre (0, R), start (0, 0); the measured turn is the last segment.
    """
    sign = 1.0 if circle.direction == "ccw" else -1.0
    full_turns, rest_rad = divmod(circle.omega_rad_s * LEAD_IN_S, 2.0 * math.pi)
    joint = _point_mm(circle.radius_mm, -0.5 * math.pi + sign * rest_rad)
    arc = {"center_mm": [0.0, circle.radius_mm], "direction": circle.direction, "plane": "xy"}
    lead_in = [{"arc": {**arc, "to_mm": [0.0, 0.0]}}] * int(full_turns) + [{"arc": {**arc, "to_mm": joint}}]
    return {"axes": ["x", "y"], "start_mm": [0.0, 0.0], "feed_mm_min": circle.feed_mm_min,
            "segments": lead_in + [{"arc": {**arc, "to_mm": joint}}]}


def circle_scenario(base: Scenario, setting: Setting, circle: GridCircle) -> Scenario:
    """``base`` running one grid circle with ``setting``."""
    overrides = {**setting.overrides(base.axes), "limits": {"max_acceleration_mm_s2": GRID_ACCELERATION_MM_S2}}
    return base.variant(overrides, program=circle_program(circle), settle_s=SETTLE_S, duration_s=None,
                        name=f"{base.name}[{setting.name} {circle.label}]")


@dataclass(frozen=True)
class CircleMeasure:
    """The measured turn of one circle: radius reduction and largest |radial deviation| [µm], samples."""

    circle: GridCircle
    radius_reduction_um: float
    max_abs_deviation_um: float
    n_samples: int


def steady_points_m(record: RunRecord) -> np.ndarray:
    """Measured xy positions (M, 2) [m] at the stamps where the reference is on the last segment and not done."""
    reference = record.reference
    if reference is None:
        raise CncError("the run recorded no reference, so the measured turn cannot be told apart")
    stamp_ns, position_m = measured_positions(record)
    _, rows, ref_rows = np.intersect1d(stamp_ns, reference.stamp_ns, return_indices=True)
    keep = (reference.segment_index[ref_rows] == len(record.program.segments) - 1) & ~reference.done[ref_rows]
    return position_m[rows[keep]][:, :2]


def measure_circle(item: tuple[Scenario, GridCircle]) -> CircleMeasure:
    """Run one grid circle on the engine and measure its full turn (module level: picklable for executors)."""
    scenario, circle = item
    points = steady_points_m(run_engine(scenario))
    if points.shape[0] < 16:
        raise CncError(f"{scenario.name}: the measured turn has {points.shape[0]} samples, needs >= 16")
    deviation_um = (np.hypot(points[:, 0], points[:, 1] - circle.radius_mm / MM_PER_M)
                    - circle.radius_mm / MM_PER_M) * UM_PER_M
    return CircleMeasure(circle, float(-np.mean(deviation_um)), float(np.max(np.abs(deviation_um))),
                         int(points.shape[0]))


def grid_measures(executor: Executor, base: Scenario, settings: Sequence[Setting],
                  circles: Sequence[GridCircle]) -> dict[str, list[CircleMeasure]]:
    """Every circle under every setting, in one map over the executor: setting name -> measures (circle order)."""
    items = [(circle_scenario(base, s, c), c) for s in settings for c in circles]
    measures = executor.map(measure_circle, items, label="paper003 grid")
    n = len(circles)
    return {s.name: measures[i * n:(i + 1) * n] for i, s in enumerate(settings)}


def predicted_radius_gain(model: p3.Paper003Model, ff1: float, omega_rad_s: float) -> float:
    """``|G(jω)|`` of the module docstring: the measured circle's radius over the programmed one."""
    s = 1j * omega_rad_s
    c = model.torque_per_inertia
    h = (c * model.k2 * s + c * model.k1) / (s * s + c * model.k2 * s + c * model.k1)
    k = model.position_gain_1_s
    delay = cmath.exp(-0.5 * s * model.sample_time_s)  # the zero-order hold's mean delay
    return abs(h * (k + ff1 * s) / (s + k * h * delay) / (1.0 + model.t_ip_s * s))


def predicted_reduction_um(model: p3.Paper003Model, ff1: float, circle: GridCircle) -> float:
    """``R (1 − |G(jω)|)`` [µm]: the linear prediction of :attr:`CircleMeasure.radius_reduction_um`."""
    return circle.radius_mm * 1000.0 * (1.0 - predicted_radius_gain(model, ff1, circle.omega_rad_s))


def rise_scenario(base: Scenario, setting: Setting) -> Scenario:
    """A line along x at the paper's rise-time feed, started as a step (no acc/dec filter)."""
    overrides = {**setting.overrides(base.axes), "limits": {"max_acceleration_mm_s2": STEP_ACCELERATION_MM_S2},
                 "interpolator": {"accel_decel": {"kind": "none"}}}
    program = {"shape": "line", "length_mm": STEP_LENGTH_MM, "feed_mm_min": data.RISE_FEED_MM_MIN, "angle_deg": 0.0}
    return base.variant(overrides, program=program, settle_s=SETTLE_S, duration_s=None,
                        name=f"{base.name}[{setting.name} step]")


def rise_time_s(time_s: np.ndarray, velocity_m_s: np.ndarray, final_m_s: float) -> float:
    """10-90 % rise time of ``velocity_m_s`` towards ``final_m_s`` [s] (first crossings, linearly interpolated)."""
    def crossing(level: float) -> float:
        above = np.flatnonzero(velocity_m_s >= level * final_m_s)
        if above.size == 0 or above[0] == 0:
            raise CncError(f"the velocity never crosses {level:.0%} of {final_m_s} m/s after rest")
        i = int(above[0])
        v0, v1 = velocity_m_s[i - 1], velocity_m_s[i]
        return float(time_s[i - 1] + (level * final_m_s - v0) / (v1 - v0) * (time_s[i] - time_s[i - 1]))

    return crossing(0.9) - crossing(0.1)


def measure_rise_time_s(scenario: Scenario) -> float:
    """Run the feed step on the engine; the 10-90 % rise time of the x velocity to the programmed feed [s]."""
    record = run_engine(scenario)
    joints = record.joint_states
    return rise_time_s(joints.stamp_ns * 1e-9, joints.velocity_m_s[:, 0], data.RISE_FEED_MM_MIN / 60000.0)


@dataclass(frozen=True)
class GridObjective:
    """Mean over ``circles`` of the largest |radial deviation| of the measured turn [µm], at a setting.

    A picklable function of the point ``x`` of :data:`SETTING_VARIABLES` (the tuner's
    :class:`~cnc_tools.tuning.objectives.Objective`); a run that faults scores +inf.
    """

    base: Scenario
    circles: tuple[GridCircle, ...]
    unit: str = "um"

    def __call__(self, x: np.ndarray) -> float:
        setting = setting_at("candidate", x)
        try:
            measures = [measure_circle((circle_scenario(self.base, setting, c), c)) for c in self.circles]
        except CncError:
            return math.inf
        return float(np.mean([m.max_abs_deviation_um for m in measures]))


def summary_um(measures: Sequence[CircleMeasure]) -> Mapping[str, float]:
    """Max and mean over the circles of the radius reduction and of the largest |deviation| [µm]."""
    reduction = np.array([m.radius_reduction_um for m in measures])
    largest = np.array([m.max_abs_deviation_um for m in measures])
    return {"reduction_max_um": float(reduction.max()), "reduction_mean_um": float(reduction.mean()),
            "deviation_max_um": float(largest.max()), "deviation_mean_um": float(largest.mean())}
