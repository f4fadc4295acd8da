"""The cases of the paper-004 bench: regulator, switch, start and preview of each run, and running them.

Every run is the closed loop of :mod:`.sim` on the paper's scenario
(:mod:`.data`): 500 N, 0.2 mm/rev, 600 rpm, 12 s, depth 1 -> 2 -> 3 mm every 4 s,
sample 1 ms, override updated every 10 ms. "Steady" starts cutting at the
reference with the continuous ratio for 1 mm (quantised by the switch);
"rest" starts with no force and the feed axis at rest.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from cnc_contour_control.force import (
    DepthSchedule,
    ForceRegulator,
    ForceRegulatorConfig,
    PreviewConfig,
    QuantiserConfig,
    StepPlan,
    TurningModelConfig,
    plan_schedule,
)
from cnc_plant_sim.process.turning import TurningConfig
from cnc_tools.reproductions.paper004 import data
from cnc_tools.reproductions.paper004.metrics import Segment, segments, switchings_per_s
from cnc_tools.reproductions.paper004.sim import Loop, Traces, simulate

#: Period of the override updates [s] (the paper gives none; a PMC scan of the order of 10 ms).
UPDATE_PERIOD_S = 0.01
#: The bench's sample time [s].
SAMPLE_S = 1.0e-3


def paper_model() -> TurningModelConfig:
    """The nominal model of the scenario (depth bounds 1-3 mm)."""
    return TurningModelConfig(specific_force_n_mm2=data.SPECIFIC_FORCE_N_MM2, spindle_rpm=data.SPINDLE_RPM,
                              programmed_feed_mm_rev=data.PROGRAMMED_FEED_MM_REV,
                              interpolator_tau_s=data.INTERPOLATOR_TAU_S, depth_min_mm=1.0, depth_max_mm=3.0)


def switch(quantised: bool) -> QuantiserConfig:
    """The FANUC 0T switch, or the same range without levels."""
    return QuantiserConfig(**{**data.SWITCH, "step_ratio": data.SWITCH["step_ratio"] if quantised else 0.0})


@dataclass(frozen=True)
class Case:
    """One run of the bench.

    ``preview``: the depth schedule the program gives the planner (None: feedback only), right or wrong.
    """

    key: str
    label: str
    law: str
    quantised: bool
    from_rest: bool = False
    law_params: Mapping[str, Any] = field(default_factory=dict)
    preview: tuple[tuple[float, float], ...] | None = None
    hysteresis_fraction: float = 0.0


def _smc_params() -> dict[str, Any]:
    return dict(data.SMC_PARAMS)


#: The paper's comparison (Figs. 1, 2, 4, 5) and the PI, from steady cutting.
MAIN_CASES: tuple[Case, ...] = tuple(
    Case(f"{law}/{'4bit' if q else 'cont'}", f"{name}, {'4-bit' if q else 'continuous'}", law, q,
         law_params=_smc_params() if law == "smc" else {})
    for law, name in (("adaptive", "adaptive"), ("smc", "SMC"), ("pi", "PI")) for q in (False, True))

#: The boundary layer's widths of the chattering study (ε; Φ = ε F_ref λ).
EPSILONS: tuple[float, ...] = (0.01, 0.025, 0.05, 0.1, 0.2)
#: The boundary layer's width against chattering, 4-bit.
EPSILON_CASES: tuple[Case, ...] = tuple(
    Case(f"smc-eps{eps:g}/4bit", f"SMC ε {100 * eps:g} %, 4-bit", "smc", True,
         law_params={**data.SMC_PARAMS, "epsilon_fraction": eps}) for eps in EPSILONS)

#: The SMC from rest (does η = 0.1 reach the reference?).
REST_CASES: tuple[Case, ...] = tuple(
    Case(f"smc-rest/{'4bit' if q else 'cont'}", f"SMC from rest, {'4-bit' if q else 'continuous'}", "smc", q,
         from_rest=True, law_params=_smc_params()) for q in (False, True))


def _shifted(shift_s: float = 0.0, depth_scale: float = 1.0) -> tuple[tuple[float, float], ...]:
    return tuple((t + shift_s if t > 0.0 else t, d * depth_scale) for t, d in data.DEPTH_SCHEDULE)


#: The preview with the right schedule and deliberately wrong ones (SMC as the feedback law).
PREVIEW_CASES: tuple[Case, ...] = (
    Case("preview/cont", "SMC + preview, continuous", "smc", False, law_params=_smc_params(), preview=_shifted()),
    Case("preview/4bit", "SMC + preview, 4-bit", "smc", True, law_params=_smc_params(), preview=_shifted()),
    Case("preview-late/4bit", "preview 0.1 s late, 4-bit", "smc", True, law_params=_smc_params(),
         preview=_shifted(0.1)),
    Case("preview-early/4bit", "preview 0.1 s early, 4-bit", "smc", True, law_params=_smc_params(),
         preview=_shifted(-0.1)),
    Case("preview-deep/4bit", "preview depths +25 %, 4-bit", "smc", True, law_params=_smc_params(),
         preview=_shifted(0.0, 1.25)),
    Case("preview-pi/4bit", "PI + preview, 4-bit", "pi", True, preview=_shifted()),
)


#: Ours without the depth-jump test (``depth_jump_fraction`` 0): the step is seen by the surface alone.
OURS_NO_JUMP = Case("ours-no-jump/4bit", "ours without the depth-jump test, 4-bit", "smc_integral", True,
                    law_params={**data.OURS_PARAMS, "depth_jump_fraction": 0.0},
                    hysteresis_fraction=data.OURS_HYSTERESIS)

#: Ours: the paper's SMC to reach the layer, an integral inside it, the switch's hysteresis (``smc_integral``).
OURS_CASES: tuple[Case, ...] = (
    Case("ours/cont", "ours (SMC + integral), continuous", "smc_integral", False, law_params=data.OURS_PARAMS),
    Case("ours/4bit", "ours (SMC + integral), 4-bit", "smc_integral", True, law_params=data.OURS_PARAMS,
         hysteresis_fraction=data.OURS_HYSTERESIS),
    Case("preview-ours/4bit", "ours + preview, 4-bit", "smc_integral", True, law_params=data.OURS_PARAMS,
         preview=_shifted(), hysteresis_fraction=data.OURS_HYSTERESIS),
)


@dataclass(frozen=True)
class Result:
    """A run: its case, traces, segment measures and switching rate; the plans it used."""

    case: Case
    traces: Traces
    segments: list[Segment]
    switchings_per_s: float
    plans: tuple[StepPlan, ...] = ()


#: The default preview window (a frozen config, shared by the defaults below).
DEFAULT_PREVIEW = PreviewConfig()


def plans_for(case: Case, preview: PreviewConfig = DEFAULT_PREVIEW) -> tuple[StepPlan, ...]:
    """The preview plans of ``case`` on the nominal model (none without a preview)."""
    if case.preview is None:
        return ()
    return plan_schedule(paper_model(), DepthSchedule(case.preview), data.REFERENCE_N, UPDATE_PERIOD_S,
                         switch(case.quantised), preview)


def run_case(case: Case, duration_s: float = data.DURATION_S, preview: PreviewConfig = DEFAULT_PREVIEW) -> Result:
    """Run ``case`` on the paper's scenario (``duration_s`` shorter for quick checks)."""
    model = paper_model()
    config = ForceRegulatorConfig(law=case.law, law_params=case.law_params, quantiser=switch(case.quantised),
                                  update_period_s=UPDATE_PERIOD_S, hysteresis_fraction=case.hysteresis_fraction)
    plans = plans_for(case, preview)
    loop = Loop(model, TurningConfig(specific_force_n_mm2=model.specific_force_n_mm2, spindle_rpm=model.spindle_rpm,
                                     depth_schedule=data.DEPTH_SCHEDULE),
                dt_s=SAMPLE_S, duration_s=duration_s, from_rest=case.from_rest)
    traces = simulate(loop, ForceRegulator(config, plans), data.REFERENCE_N)
    schedule = DepthSchedule(data.DEPTH_SCHEDULE)
    return Result(case, traces, segments(traces, schedule, data.REFERENCE_N, data.BAND_FRACTION),
                  switchings_per_s(traces), plans)


def step_phase_overshoots(case: Case, depths_mm: tuple[float, float], phases_s: Sequence[float],
                          lead_s: float = 0.5, after_s: float = 0.5) -> list[float]:
    """The overshoot [%] of one depth step ``depths_mm`` under ``case`` (no preview), for each phase of the step
    in the update period: steady cutting at the first depth, the step at ``lead_s`` + phase [s] (an update falls
    1 ms after ``lead_s``), the peak within ``after_s`` [s] after it."""
    model, out = paper_model(), []
    for phase_s in phases_s:
        step_s = lead_s + phase_s
        schedule = ((0.0, depths_mm[0]), (step_s, depths_mm[1]))
        config = ForceRegulatorConfig(law=case.law, law_params=case.law_params, quantiser=switch(case.quantised),
                                      update_period_s=UPDATE_PERIOD_S, hysteresis_fraction=case.hysteresis_fraction)
        loop = Loop(model, TurningConfig(specific_force_n_mm2=model.specific_force_n_mm2,
                                         spindle_rpm=model.spindle_rpm, depth_schedule=schedule),
                    dt_s=SAMPLE_S, duration_s=step_s + after_s)
        traces = simulate(loop, ForceRegulator(config), data.REFERENCE_N)
        out.append(100.0 * (float(traces.force_n[traces.t_s > step_s].max()) / data.REFERENCE_N - 1.0))
    return out
