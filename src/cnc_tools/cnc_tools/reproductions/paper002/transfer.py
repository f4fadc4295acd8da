"""Paper 002's PDC carried to papers 000 and 001: their plants with a periodic load, their own laws, PDC on top.

Beyond paper 002 (issue 10, item 3). Each :class:`Target` is a paper's
contour run (its scenario) with a periodic load ``A sin(2π f_d t + θ)`` at
the plant input (``plant.periodic_load``, :mod:`cnc_plant_sim.models.periodic_load`;
A in the plant's command unit, θ 0 on X and 1 rad on Y as paper 002's
scenario) and three runs on the engine:

- ``floor``: the paper's own law, no load (the error's own f_d content);
- ``law``: the paper's own law under the load;
- ``law+pdc``: the same law with the PDC stacked on it (``pid_pdc`` /
  ``fuzzy_pdc``, :mod:`cnc_contour_control.laws.pdc_stack`), P_n of each
  axis derived from the plant config (:func:`cnc_plant_sim.models.nominal_models.
  drive_velocity_model`: the nominal drive, ZOH at the servo's period; the
  run's plant is drawn with the paper's random variation, so P_n is off by
  up to ±5 % in K and τ on paper 000).

Measured at constant speed (:mod:`.measures`): the RMS of the signed contour
error [µm] and its f_d line (lock-in amplitude) [µm]; the removal share is
``1 − line(law+pdc) / line(law)``. For a linear inner law (the PID) the
loop's figures come from :mod:`cnc_contour_control.disturbance.stack_loop`
on the drawn plant of X: |S|∞ with and without the PDC, the disturbance peak
(how much any band of an input load is amplified), Eq. 13's margin, and
stability. The FLC is nonlinear: its loop figures are not computed (n/a).
"""
from __future__ import annotations

import argparse
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from cnc_contour_control.disturbance.loop import tf
from cnc_contour_control.disturbance.stack_loop import StackBlocks, pid_transfer, sampled_plant, stack_figures
from cnc_contour_control.estimators import signed_contour_error
from cnc_plant_sim.models.nominal_models import canceller_model_params, continuous_velocity_model, drive_velocity_model
from cnc_plant_sim.models.plant import PlantConfig
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.reproductions.paper000.runs import CONTROLLERS
from cnc_tools.reproductions.paper002 import data
from cnc_tools.reproductions.paper002.measures import constant_speed_mask, lock_in_amplitude, rms
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import Scenario, load_scenario

#: Metres per micrometre (the bench reports µm).
UM_PER_M = 1.0e6
#: Load phase per axis [rad] (paper 002's scenario: 0 on X, 1 on Y).
PHASES_RAD = (0.0, 1.0)
#: The stacked law of each inner law.
STACKED = {"pid": "pid_pdc", "fuzzy": "fuzzy_pdc"}
#: The three runs of a target.
RUNS = ("floor", "law", "law+pdc")


@dataclass(frozen=True)
class Target:
    """A paper's contour, its law and the periodic load (``spindle_rpm · flutes / 60`` = f_d).

    ``law_params`` None: the scenario's own gains; ``pdc_params``: the stack's PDC keys beyond the spindle
    (``spare_dof``).
    """

    key: str
    label: str
    scenario: str
    law: str
    spindle_rpm: float
    flutes: int
    amplitude: float
    unit: str
    law_params: Mapping[str, Any] | None = None
    pdc_params: Mapping[str, Any] = field(default_factory=dict)

    @property
    def f_d_hz(self) -> float:
        """The load's frequency [Hz]."""
        return self.spindle_rpm * self.flutes / 60.0

    def at(self, spindle_rpm: float, flutes: int) -> Target:
        """The same target at another spindle speed and flute count."""
        return replace(self, key=f"{self.key}@{spindle_rpm:g}x{flutes}", spindle_rpm=spindle_rpm, flutes=flutes)


#: Paper 000's circle (1.3 m/min, r 20 mm, T 10 ms, 8-bit DAC) with PID and FLC; f_d 5 Hz is paper 002's
#: f_d/f_s = 0.05 at T = 10 ms; A = 10 DAC (8 % of the DAC's range). Paper 001's circle (5 m/min, r 10 mm,
#: T 1 ms, PID 5/20/0.01 per µm) with f_d 50 Hz (750 rpm, 4 flutes) and A = 100 N.
TARGETS: dict[str, Target] = {t.key: t for t in (
    Target("000-pid", "paper 000 circle, PID", "scenarios/paper000_circle_high.yaml", "pid", 150.0, 2, 10.0, "DAC",
           CONTROLLERS["pid"].law_params),
    Target("000-flc", "paper 000 circle, FLC", "scenarios/paper000_circle_high.yaml", "fuzzy", 150.0, 2, 10.0, "DAC",
           CONTROLLERS["flc"].law_params),
    Target("001-pid", "paper 001 circle, PID", "scenarios/paper001_circle.yaml", "pid", 750.0, 4, 100.0, "N"),
)}
#: (spindle rpm, flutes) of the f_d sweep per target (where the PDC stops working): paper 000 at 5, 10, 15,
#: 20 Hz (f_s 100 Hz); paper 001 at 50, 100, 200, 280 Hz (f_s 1 kHz; more flutes: the law's rpm range ends
#: at 1400).
SWEEP: dict[str, tuple[tuple[float, int], ...]] = {
    "000-pid": ((150.0, 2), (300.0, 2), (450.0, 2), (600.0, 2)),
    "001-pid": ((750.0, 4), (1000.0, 6), (1000.0, 12), (1400.0, 12))}


def _plant(base: Scenario, target: Target, loaded: bool) -> dict[str, Any]:
    load = {"amplitude": target.amplitude if loaded else 0.0, "spindle_rpm": target.spindle_rpm,
            "flutes": target.flutes, "phases_rad": list(PHASES_RAD)}
    return {**base.raw["plant"], "periodic_load": load}


def stack_params(target: Target, gains: Mapping[str, Any], plant: PlantConfig, counts_per_m: float,
                 sample_time_s: float) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """The stacked law's shared parameters (the inner ``gains``, the spindle, the PDC's) and each axis's P_n."""
    shared = {**gains, **target.pdc_params, "spindle_rpm": target.spindle_rpm, "flutes": target.flutes}
    models = {axis: canceller_model_params(drive_velocity_model(plant, axis, counts_per_m, sample_time_s))
              for axis in plant.axes}
    return shared, models


def scenario_for(target: Target, run: str) -> Scenario:
    """The scenario of one of :data:`RUNS` for ``target`` (validated like a file)."""
    base = load_scenario(project_root() / target.scenario)
    plant = _plant(base, target, run != "floor")
    servo = {k: v for k, v in base.raw["servo"].items() if k not in ("law", "law_params", "axes")}
    gains = dict(base.raw["servo"].get("law_params", {})) if target.law_params is None else dict(target.law_params)
    servo.update(law=target.law, law_params=gains)
    if run == "law+pdc":
        shared, models = stack_params(target, gains, PlantConfig.from_mapping(plant), float(servo["counts_per_m"]),
                                      base.sample_time_s)
        servo.update(law=STACKED[target.law], law_params=shared,
                     axes={axis: {"law_params": model} for axis, model in models.items()})
    return base.variant(None, plant=plant, servo=servo, name=f"transfer_{target.key}_{run}".replace("+", "_"))


def measure_run(target: Target, run: str) -> dict[str, float]:
    """One run on the engine: RMS contour error and its f_d line at constant speed [µm]."""
    record = run_engine(scenario_for(target, run))
    error_um = signed_contour_error(record.program, record.joint_states.position_m)[0] * UM_PER_M
    mask, t = constant_speed_mask(record), record.time_s
    return {"rms_um": rms(error_um[mask]), "fd_um": lock_in_amplitude(t[mask], error_um[mask], target.f_d_hz)}


def axis_loop_figures(scenario: Scenario, axis: str, f_d_hz: float) -> dict[str, Any]:
    """A PID stack's linear figures on the drawn plant of ``axis`` (its own P_n and H)."""
    servo = next(s for s in scenario.servos if s.axis_name == axis)
    config, plant, dt = servo.law_config(), scenario.plant, scenario.sample_time_s
    velocity, position = sampled_plant(*continuous_velocity_model(plant, axis, drawn=True), servo.counts_per_m, dt)
    model = config.nominal()
    blocks = StackBlocks(velocity, position, tf(model.numerator, model.denominator),
                         pid_transfer(config.kp, config.ki, config.kd, dt), dt, tf(config.pdc_design().h))
    return {"axis": axis, **stack_figures(blocks, f_d_hz)}


def loop_figures(target: Target) -> dict[str, Any] | None:
    """The worst axis's linear figures (largest |S|∞ with the PDC; an unstable axis first); None: a nonlinear law."""
    if target.law != "pid":
        return None
    scenario = scenario_for(target, "law+pdc")
    axes = [axis_loop_figures(scenario, axis, target.f_d_hz) for axis in scenario.plant.axes]
    return max(axes, key=lambda f: (not f["stable"], f["sensitivity_peak"]))


def run_target(target: Target, runs: tuple[str, ...] = RUNS) -> dict[str, Any]:
    """The runs of ``target``, its removal share and (PID) loop figures."""
    found: dict[str, Any] = {run: measure_run(target, run) for run in runs}
    if "law" in found and "law+pdc" in found:
        found["removal"] = 1.0 - found["law+pdc"]["fd_um"] / found["law"]["fd_um"]
    found["loop"] = loop_figures(target)
    found["f_d_hz"] = target.f_d_hz
    return found


# --------------------------------------------------------------------------- the bench


def _loop_cells(loop: Mapping[str, Any] | None) -> list[object]:
    if loop is None:
        return ["n/a"] * len(LOOP_HEADER)
    return [loop["axis"], loop["sensitivity_peak"], loop["sensitivity_peak_without"], loop["disturbance_peak"],
            loop["hp_peak"], loop["eq13_margin"], "yes" if loop["stable"] else "NO"]


#: The loop figures' columns (the worst axis).
LOOP_HEADER = ("axis", "|S|inf", "|S|inf law", "dist. peak", "max|HPn|", "Eq.13", "stable")


def print_targets(found: Mapping[str, Mapping[str, Any]]) -> None:
    """The three runs of every target: RMS and f_d line [µm], removal, loop figures."""
    rows = []
    for key, entry in found.items():
        target = TARGETS[key]
        rows.append([target.label, f"{target.f_d_hz:g}", f"{target.amplitude:g} {target.unit}",
                     entry["floor"]["rms_um"], entry["floor"]["fd_um"], entry["law"]["rms_um"], entry["law"]["fd_um"],
                     entry["law+pdc"]["rms_um"], entry["law+pdc"]["fd_um"], f"{100.0 * entry['removal']:.1f} %",
                     *_loop_cells(entry["loop"])])
    print("PDC on papers 000/001 under a periodic load (contour error at constant speed, um; f_d line = lock-in); "
          f"paper 002 (its own cascade, 50 Hz): about {100.0 * data.REMOVAL_CLAIM:.0f} % removed; issue 10's goal: "
          f">= {100.0 * data.GOAL_REMOVAL:.0f} % with |S|inf <= {data.GOAL_PEAK:g}")
    print(format_table(("target", "f_d Hz", "A", "floor RMS", "floor f_d", "law RMS", "law f_d", "+PDC RMS",
                        "+PDC f_d", "removal", *LOOP_HEADER), rows))


def print_sweep(sweep: Mapping[str, Mapping[str, Any]]) -> None:
    """The f_d sweep: where the PDC stops working, with the loop figures that say why."""
    rows = []
    for key, entry in sweep.items():
        rows.append([key, f"{entry['f_d_hz']:g}", entry["law"]["rms_um"], entry["law"]["fd_um"],
                     entry["law+pdc"]["rms_um"], entry["law+pdc"]["fd_um"], f"{100.0 * entry['removal']:.1f} %",
                     *_loop_cells(entry["loop"])])
    print("f_d sweep (PID stacks): removal, RMS and the loop figures that explain a failure")
    print(format_table(("run", "f_d Hz", "law RMS", "law f_d", "+PDC RMS", "+PDC f_d", "removal", *LOOP_HEADER),
                       rows))


def paper002_transfer_bench(options: argparse.Namespace) -> int:
    """``cnc-contour bench paper002-transfer``: the targets, then (not ``--quick``) the f_d sweep."""
    started = time.perf_counter()
    found = {key: run_target(target) for key, target in TARGETS.items()}
    print_targets(found)
    points = {key: pts[:2] if options.quick else pts for key, pts in SWEEP.items()}
    sweep = {f"{key} {rpm:g} rpm x {flutes}": run_target(TARGETS[key].at(rpm, flutes), ("law", "law+pdc"))
             for key, pts in points.items() for rpm, flutes in pts}
    print()
    print_sweep(sweep)
    print(f"\nwall time {time.perf_counter() - started:.1f} s")
    write_json(getattr(options, "json", None), {"targets": found, "sweep": sweep, "machine": machine()})
    return 0
