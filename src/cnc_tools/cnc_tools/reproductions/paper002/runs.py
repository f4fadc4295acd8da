"""The runs of the paper-002 bench: one :class:`Case` -> one engine run of the paper-002 scenario -> its measures.

Every case is ``scenarios/paper002_circle.yaml`` (P position loop, K_pp 40/s,
over the identified loops of Eqs. 35-36 at 1 kHz, Coulomb/stiction friction,
A = 1.2 mm/s at f_d: the paper's periodic share of the error, see the scenario; encoder pulse 1/2.4 µm)
with, per case:

- the contour: the scenario's circle (r = 6 mm) or the line to (2, 2) mm, both
  at 120 mm/min with the scenario's 100 mm/s² (trapezoidal) acceleration;
- the law (``p`` = the paper's "none", ``dob``, ``mbda``, ``pdc``,
  ``dob_pdc``, ``mbda_pdc``) with K_pp 40/s, each axis with its own model
  (X: Eq. 35, Y: Eq. 36) and the PDC designed for ``design_rpm``;
- the periodic disturbance on or off (off: the reference run, friction and
  encoder only);
- the plant's spindle speed (``plant_rpm``; a ``step`` changes it mid-run
  through the plant's spindle schedule); ``follow``: the servo knows the
  speed it commands (the scenario's ``servo.follow_spindle``) and the PDC
  redesigns on line, else the law keeps its ``design_rpm`` design;
  ``track``: the PDC estimates f_d from its residual and redesigns for it
  (``track_fd``), with no schedule: the servo commands ``design_rpm``;
- ``encoder`` off: positions not quantised (what the law removes without the
  encoder's floor);
- ``inertia_error`` ε: None keeps the identified discrete loops; a number
  selects the plant's continuous PI loops (``loop: pi``, the identified
  poles) with K_t/J divided by 1 + ε (a ±20 % inertia error).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cnc_contour_control.core.velocity_models import PAPER002_MODELS
from cnc_contour_control.estimators import signed_contour_error
from cnc_plant_sim.models.velocity_loop import pi_loop_from_discrete
from cnc_tools.reproductions.paper002 import data
from cnc_tools.reproductions.paper002.measures import (
    FloatArray,
    constant_speed_mask,
    lock_in_amplitude,
    rms,
)
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import Scenario, load_scenario

#: The scenario every case starts from (relative to the project root).
SCENARIO = "scenarios/paper002_circle.yaml"
#: Position gain of every law [1/s] (the scenario's K_pp; the paper gives none).
KP_PER_S = 40.0
#: The laws: our name -> the paper's method.
METHODS: dict[str, str] = {"p": "none (P cascade)", "dob": "DOB", "mbda": "MBDA", "pdc": "PDC (ours, alone)",
                           "dob_pdc": "DOB+PDC", "mbda_pdc": "MBDA+PDC"}
#: Laws with a PDC.
PDC_LAWS = ("pdc", "dob_pdc", "mbda_pdc")
#: After a spindle step, the measuring window starts this late [s].
STEP_SETTLE_S = 0.3
#: The line's program (a straight line to (2, 2) mm at 120 mm/min).
LINE_PROGRAM: dict[str, Any] = {"axes": ["x", "y"], "start_mm": [0.0, 0.0],
                                "segments": [{"line": {"to_mm": list(data.LINE_TO_MM),
                                                       "feed_mm_min": data.FEED_MM_MIN}}]}


@dataclass(frozen=True)
class Case:
    """One run (see the module docstring); ``duration_s`` None runs the whole contour."""

    key: str
    contour: str
    law: str
    periodic: bool = True
    inertia_error: float | None = None
    plant_rpm: float = data.SPINDLE_RPM
    design_rpm: float = data.SPINDLE_RPM
    step: tuple[float, float] | None = None
    duration_s: float | None = None
    keep_trace: bool = False
    encoder: bool = True
    follow: bool = False
    track: bool = False

    @property
    def f_d_hz(self) -> float:
        """The disturbance frequency the plant has where the case is measured [Hz] (after a step: the new one)."""
        rpm = self.step[1] if self.step is not None else self.plant_rpm
        return rpm * data.FLUTES / 60.0


@dataclass(frozen=True)
class Measure:
    """What a run gives at constant speed: RMS contour error [pulse], its f_d line [pulse] at ``f_d_hz``, the
    window [s] and its samples."""

    rms_pulse: float
    fd_pulse: float
    f_d_hz: float
    window_s: tuple[float, float]
    samples: int


@dataclass(frozen=True)
class Result:
    """A case, its measure, and (``keep_trace``) the signed contour error [pulse] over time [s]."""

    case: Case
    measure: Measure
    trace_t_s: FloatArray | None = None
    trace_pulse: FloatArray | None = None


def _plant_overrides(case: Case) -> dict[str, Any]:
    axes: dict[str, dict[str, Any]] = {}
    for axis in ("x", "y"):
        entry: dict[str, Any] = {} if case.periodic else {"disturbance_amplitude_mm_s": 0.0}
        if case.inertia_error is not None:
            nominal = pi_loop_from_discrete(PAPER002_MODELS[axis])
            entry.update(loop="pi", torque_per_inertia=nominal.torque_per_inertia / (1.0 + case.inertia_error))
        axes[axis] = entry
    spindle: dict[str, Any] = {"spindle_rpm": case.plant_rpm}
    if not case.encoder:
        spindle["encoder_pulse_m"] = 0.0
    if case.step is not None:
        spindle.update(spindle_schedule_t_s=[case.step[0]], spindle_schedule_rpm=[case.step[1]])
    return {"plant": {"axis_overrides": axes, "velocity_loop": spindle}}


def disturbance_amplitude_mm_s() -> float:
    """The scenario's periodic disturbance amplitude A [mm/s] (X's; Y has the same)."""
    base = load_scenario(project_root() / SCENARIO)
    return float(base.plant.axis_overrides["x"]["disturbance_amplitude_mm_s"])


def law_params(law: str, design_rpm: float = data.SPINDLE_RPM) -> dict[str, Any]:
    """The law's parameters of every case: K_pp, and the PDC's spindle speed for a law with a PDC."""
    params: dict[str, Any] = {"kp": KP_PER_S}
    if law in PDC_LAWS:
        params["spindle_rpm"] = design_rpm
    return params


def _servo(base: Scenario, case: Case) -> dict[str, Any]:
    servo = {k: v for k, v in base.raw["servo"].items() if k not in ("law", "law_params", "axes")}
    params = {**law_params(case.law, case.design_rpm), **({"track_fd": True} if case.track else {})}
    servo.update(law=case.law, law_params=params, follow_spindle=case.follow)
    if case.law != "p":
        servo["axes"] = {"y": {"law_params": {"model": "y"}}}  # each axis its own P_n (Eq. 36 for Y)
    return servo


def scenario_for(case: Case) -> Scenario:
    """The scenario of ``case`` (validated like a file)."""
    base = load_scenario(project_root() / SCENARIO)
    changes: dict[str, Any] = {"servo": _servo(base, case), "name": f"paper002_{case.key.replace('/', '_')}"}
    if case.contour == "line":
        changes["program"] = LINE_PROGRAM
    if case.duration_s is not None:
        changes["duration_s"] = case.duration_s
    return base.variant(_plant_overrides(case), **changes)


def _window(record: RunRecord, case: Case) -> np.ndarray:
    mask = constant_speed_mask(record)
    if case.step is not None:
        mask &= record.time_s >= case.step[0] + STEP_SETTLE_S
    return mask


def measure(record: RunRecord, case: Case) -> tuple[Measure, FloatArray]:
    """The case's measure, and the signed contour error of the whole run [pulse]."""
    error_pulse = signed_contour_error(record.program, record.joint_states.position_m)[0] / data.M_PER_PULSE
    mask, t = _window(record, case), record.time_s
    found = Measure(rms(error_pulse[mask]), lock_in_amplitude(t[mask], error_pulse[mask], case.f_d_hz),
                    case.f_d_hz, (float(t[mask][0]), float(t[mask][-1])), int(np.count_nonzero(mask)))
    return found, error_pulse


def run_case(case: Case) -> Result:
    """Run ``case`` on the engine and measure it (module level: executors pickle it)."""
    record = run_engine(scenario_for(case))
    found, error_pulse = measure(record, case)
    if not case.keep_trace:
        return Result(case, found)
    return Result(case, found, record.time_s.astype(np.float32), error_pulse.astype(np.float32))
