"""Learning sessions of the ``paper001`` bench: a contour, a compensator stack, runs with the state carried over.

The paper's "iterations" are repeated runs of the same path with the
network's weights carried over. A *session* here is that loop on the engine:
run k reads the learned state run k − 1 wrote (``compensator.state_in`` =
the previous ``state_out``, a ``.npz`` per run under the session's folder), so
run 1 starts fresh and run k starts from k − 1 runs of learning.

- Stacks come from :data:`STACKS` by name: ``pid`` (PID alone, no estimator
  or compensator), ``nn-paper-mm`` and ``nn-paper-um`` (Section 2.3's law with
  the paper's η = 0.05, α = 0.15, β = 1, 8-5-2, errors and inputs in mm or
  errors in µm), ``nn`` (our stated setting), ``ccc`` (Koren's cross-coupled
  controller), ``ilc`` (contour-space ILC) and ``file`` (the scenario
  file's own estimator and compensator sections). Every parameter we changed
  from a config default is in the stack's ``params`` and printed by the bench.
- Each run is measured by :func:`measure_run`: ε_peak and ε_ISE as
  :func:`~cnc_tools.reproductions.paper001.readings.measure` reports them
  (the scorer's exact contour error from the first reference to the end of
  the run; ISE = Σε² over the 1 ms samples, ε in mm), the peak while the
  reference moves, the error after the start transient and the largest
  compensation.
- :func:`run_sessions` runs independent sessions, in one process or in
  worker processes; each session is deterministic on its own, so the results
  do not depend on the number of workers.
"""
from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.axis.servo import NO_FERROR_TRIP
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.units import M_PER_MM
from cnc_tools.analysis.scoring import contour_error_series
from cnc_tools.reproductions.paper001.data import SCENARIOS, TABLE1_NETWORK
from cnc_tools.reproductions.paper001.readings import measure, reading_named
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.executor import LocalExecutor
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import Scenario, load_scenario

#: Scenarios of the bench beyond Tables 2 and 3, relative to the project root.
CUTTING_SCENARIO = "scenarios/paper001/circle_cutting.yaml"
PAPER000_SCENARIO = "scenarios/paper001/paper000_circle_nn.yaml"
#: Scenario files by key: the two contours of Tables 2 and 3, Fig. 8's load, paper 000's circle with the network.
SCENARIO_FILES: dict[str, str] = {**SCENARIOS, "circle_cutting": CUTTING_SCENARIO, "paper000_circle": PAPER000_SCENARIO}
#: "After the start transient": samples from this time after the first reference [s].
LATE_FROM_S = 0.3
#: A clip of the network's and the baselines' outputs [N] far above what they reach: a guard, not a limit
#: (the configs' default 100 is sized for paper 000's DAC units; the PID alone peaks near 2 kN).
OUTPUT_LIMIT_N = 1.0e4

#: Section 2.3 as printed: η 0.05 and α 0.15 (text beside Eq. 20), 8-5-2 (Table 1), β = 1 (Eqs. 14-15 carry
#: no β), errors and position inputs in mm, the previous outputs u_N fed back unscaled.
PAPER_NN_PARAMS: dict[str, Any] = {
    "hidden_units": int(TABLE1_NETWORK["hidden"]), "eta": TABLE1_NETWORK["learning_rate"],
    "alpha": TABLE1_NETWORK["momentum"], "beta": 1.0, "position_input_scale_per_m": 1.0e3,
    "output_input_scale": 1.0, "error_scale_per_m": 1.0e3, "output_limit": OUTPUT_LIMIT_N}


#: ``Stack.method`` of the PID alone, and of "the scenario file's compensator".
PID_ALONE, FROM_FILE = "", "from-file"


@dataclass(frozen=True)
class Stack:
    """A compensator stack on top of the axes' PIDs.

    Attributes
    ----------
    name, label : str
        Registry key; table label.
    method : str
        Compensator registry name; :data:`PID_ALONE` drops the estimator and compensator stages,
        :data:`FROM_FILE` keeps the scenario file's own sections.
    params : Mapping
        The compensator's parameters (config fields; the rest keep the config's defaults).
    why : str
        What the stack is and why its parameters are what they are.
    """

    name: str
    label: str
    method: str
    params: Mapping[str, Any]
    why: str

    @property
    def learns(self) -> bool:
        """True when runs carry something over (ILC, network)."""
        return self.method in ("ilc", "neural", FROM_FILE)


def _stacks() -> dict[str, Stack]:
    found = (
        Stack("pid", "PID", PID_ALONE, {}, "the axes' PIDs alone, no estimator or compensator stage"),
        Stack("nn-paper-mm", "PID+NN paper (mm)", "neural", dict(PAPER_NN_PARAMS),
              "Section 2.3 as printed, errors in mm (Tables 2-3's unit)"),
        Stack("nn-paper-um", "PID+NN paper (µm)", "neural", {**PAPER_NN_PARAMS, "error_scale_per_m": 1.0e6},
              "Section 2.3 as printed, errors in µm (the unit our reading gives the PID's error)"),
        Stack("nn", "PID+NN ours", "neural",
              {**PAPER_NN_PARAMS, "eta": 3.0e-3, "beta": 30.0, "output_input_scale": 1.0e-3},
              "η 0.003 (1/17 of the paper's), β 30, u_N fed back per kN; the rest as printed"),
        Stack("ccc", "PID+CCC", "ccc", {"kp": 5.0e6, "ki": 2.0e7, "kd": 1.0e4, "integral_limit": OUTPUT_LIMIT_N,
                                        "output_limit": OUTPUT_LIMIT_N},
              "Koren's CCC with the axis PID's own gains on ε_c (5 N/µm, 20 N/(µm s), 0.01 N s/µm)"),
        Stack("ilc", "PID+ILC", "ilc", {"learning_gain": 1.0e6, "advance_samples": 15, "cutoff_hz": 40.0,
                                        "output_limit": OUTPUT_LIMIT_N},
              "L 1 N/µm (1/5 of K_p), d = π/(2 ω_n T) = 15 samples, Q 40 Hz (passes the 14-17 Hz resonance)"),
        Stack("file", "PID+NN (file)", FROM_FILE, {}, "the scenario file's estimator and compensator sections"),
    )
    return {stack.name: stack for stack in found}


#: Stacks by name.
STACKS: dict[str, Stack] = _stacks()


# =========================================================================== one run, measured
@dataclass(frozen=True)
class RunMeasure:
    """One run of a session: ε_peak [mm], ISE [mm²] and the rest (see the module docstring)."""

    run: int
    peak_mm: float
    peak_motion_mm: float
    ise_mm2: float
    late_peak_mm: float
    late_rms_mm: float
    compensation_max: float
    fault: str | None
    diverged: bool


def late_errors_mm(record: RunRecord) -> np.ndarray:
    """The exact contour error [mm] from :data:`LATE_FROM_S` after the first scored sample while the reference moves.

    The window of the cutting-load figures in docs/reproduction.md: after the start transient, before the stop.
    """
    series, _ = contour_error_series(record)
    keep = (series.stamp_ns - series.stamp_ns[0]) * 1e-9 >= LATE_FROM_S
    if record.reference is not None:
        keep &= np.isin(series.stamp_ns, record.reference.stamp_ns[record.reference.feed_m_s > 0.0])
    return series.error_m[keep] / M_PER_MM


def measure_run(record: RunRecord, run: int, sample_time_s: float) -> RunMeasure:
    """Measure ``record`` (run number ``run``) with the unit study's :func:`measure` plus the late window."""
    found = measure(record, sample_time_s)
    late = late_errors_mm(record)
    compensation = record.compensation
    largest = float(np.max(np.abs(compensation.correction))) if compensation is not None else 0.0
    return RunMeasure(run, found["peak_mm"], found["peak_motion_mm"], found["ise_mm2"],
                      float(late.max()) if late.size else math.nan,
                      float(np.sqrt(np.mean(late ** 2))) if late.size else math.nan, largest,
                      record.summary.get("compensator", {}).get("fault"), bool(found["diverged"]))


def failed_run(run: int, reason: str) -> RunMeasure:
    """A run that raised a fault (the plant or a stage refused a value): diverged, values NaN."""
    return RunMeasure(run, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, reason, True)


# =========================================================================== sessions
def stack_scenario(base: Scenario, stack: Stack, params: Mapping[str, Any] | None = None, state_in: str = "",
                   state_out: str = "", freeze: bool = False) -> Scenario:
    """``base`` with ``stack`` (its params updated by ``params``); the PID alone drops both stages.

    :data:`FROM_FILE` keeps ``base``'s compensator section and merges ``params`` into its params.
    """
    if stack.method == PID_ALONE:
        return base.variant(estimator=None, compensator=None)
    files = {"state_in": state_in, "state_out": state_out, "freeze": freeze}
    if stack.method == FROM_FILE:
        if base.compensator is None:
            raise ConfigError(f"stack {stack.name!r} needs a compensator section in scenario {base.name!r}")
        return base.variant({"compensator": {**files, "params": dict(params or {})}})
    section = {"method": stack.method, "params": {**dict(stack.params), **dict(params or {})}, **files}
    return base.variant(estimator={"method": "window"}, compensator=section)


def state_path(folder: Path, run: int) -> Path:
    """The state file run ``run`` (1-based) writes in a session's ``folder``."""
    return folder / f"run_{run:03d}.npz"


def learning_runs(scenario: Scenario, runs: int, folder: Path) -> Iterator[tuple[Scenario, RunRecord]]:
    """Run ``scenario`` ``runs`` times, run k starting from run k − 1's state file; yield each run and its record.

    The first run starts from the scenario's own ``state_in`` (empty: fresh).
    A scenario without a compensator just runs ``runs`` times.
    """
    previous = scenario.compensator.state_in if scenario.compensator is not None else ""
    for run in range(1, runs + 1):
        current = scenario
        if scenario.compensator is not None:
            out = state_path(folder, run)
            current = scenario.variant({"compensator": {"state_in": previous, "state_out": str(out)}})
            previous = str(out)
        yield current, run_engine(current)


@dataclass(frozen=True)
class SessionSpec:
    """What a session runs: a scenario file (key of :data:`SCENARIO_FILES`), a stack, its changes, how many runs.

    ``state_in`` starts run 1 from a learned state; ``freeze`` applies it without learning. ``reading`` names a
    unit reading of :data:`~cnc_tools.reproductions.paper001.readings.READINGS` applied to the scenario (empty:
    the scenario file's own, the reproduction's reading).
    """

    key: str
    scenario: str
    stack: str
    runs: int
    folder: str
    params: Mapping[str, Any] = field(default_factory=dict)
    state_in: str = ""
    freeze: bool = False
    reading: str = ""


@dataclass(frozen=True)
class Session:
    """A finished session: its spec and one measure per run (fewer than asked when a run faulted)."""

    spec: SessionSpec
    runs: tuple[RunMeasure, ...]

    def at(self, run: int) -> RunMeasure:
        """Run ``run`` (1-based), or the last run made when the session stopped earlier."""
        return self.runs[min(run, len(self.runs)) - 1]

    def last_state(self) -> Path:
        """The state file the last run wrote."""
        return state_path(Path(self.spec.folder), len(self.runs))

    def to_json(self) -> dict[str, Any]:
        """Plain data: the spec and every run's measure."""
        return {"spec": asdict(self.spec), "runs": [asdict(r) for r in self.runs]}


def run_session(spec: SessionSpec) -> Session:
    """Run ``spec``'s session on the engine; a faulted run ends it (recorded as diverged)."""
    stack = STACKS[spec.stack]
    # the paper's runs have no trip: a session watches what learning does to the loop, ringing included
    base = load_scenario(project_root() / SCENARIO_FILES[spec.scenario], {"servo": NO_FERROR_TRIP})
    if spec.reading:
        base = reading_named(spec.reading).apply(base)
    scenario = stack_scenario(base, stack, spec.params, spec.state_in, freeze=spec.freeze)
    measures: list[RunMeasure] = []
    runs = learning_runs(scenario, spec.runs, Path(spec.folder))
    while len(measures) < spec.runs:
        try:
            _, record = next(runs)
        except FaultError as err:
            measures.append(failed_run(len(measures) + 1, str(err)))
            break
        measures.append(measure_run(record, len(measures) + 1, scenario.sample_time_s))
    return Session(spec, tuple(measures))


def run_sessions(specs: Sequence[SessionSpec], workers: int = 1) -> dict[str, Session]:
    """Every session of ``specs`` by key, in ``workers`` processes (1: in this process), through a LocalExecutor."""
    keys = [spec.key for spec in specs]
    if len(set(keys)) != len(keys):
        raise ConfigError(f"session keys must be unique, got {keys}")
    with LocalExecutor(max(1, workers)) as executor:
        return dict(zip(keys, executor.map(run_session, specs, label="paper001 sessions")))
