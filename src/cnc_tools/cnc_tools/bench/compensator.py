"""Bench ``compensator``: cost per tick of each compensator, as a ratio to one servo sample, in one process.

Side by side, round after round in the same process (so all see the same
machine load), in CPU time (``time.process_time``), the median over rounds:

- the yardstick: one ``ServoController.parts`` (paper 000's PID, one axis);
- ``neural`` (paper 001's 8-5-2 network: learning from the previous tick's pass
  and the forward pass of this one), the same network frozen (forward only),
  ``ccc``, ``ilc`` during a run, the ILC's run-to-run update (``end_run``, its
  cost spread over the run's ticks), and ``none``;
- the framework we could have used instead of the hand-written passes:
  scikit-learn's ``MLPRegressor`` with the same 8-5-2 shape (tanh hidden
  layer, linear outputs), SGD with momentum 0.15, ``partial_fit`` on one
  sample: a forward pass, a backward pass and an update, as our step.

The samples are a 1 kHz circle (R = 10 mm, 5 m/min) with a position lagging
the reference, so the network learns from realistic errors; it must end
without a fault (a tripped guard would make its step cheap).
"""
from __future__ import annotations

import argparse
import math
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.compensators import CompensatorSample, make_compensator
from cnc_contour_control.core.errors import CncError
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json

DT_S = 0.001
AXES = ("x", "y")
RADIUS_M, FEED_M_S, LAG_S = 0.01, 5.0 / 60.0, 0.004
#: Our network's settings (a learning rate that stays sane on these errors).
NEURAL = {"eta": 5e-4}

#: A case: run one batch, return how many steps it made (timed by the caller).
Case = Callable[[], int]


def circle_samples(count: int) -> list[CompensatorSample]:
    """``count`` ticks of a CCW circle, the position ``LAG_S`` behind the reference, 5 µm inside it."""
    omega, samples = FEED_M_S / RADIUS_M, []
    for k in range(count):
        s = CompensatorSample(2, DT_S)
        phi, lagged = omega * k * DT_S, omega * (k * DT_S - LAG_S)
        s.tick = k
        s.ref_position_m = [RADIUS_M * math.cos(phi), RADIUS_M * math.sin(phi)]
        s.position_m = [(RADIUS_M - 5e-6) * math.cos(lagged), (RADIUS_M - 5e-6) * math.sin(lagged)]
        s.tracking_error_m = [r - p for r, p in zip(s.ref_position_m, s.position_m)]
        s.contour_error_m, s.angle_rad = 5e-6, lagged + math.pi / 2
        samples.append(s)
    return samples


def compensator_case(name: str, params: dict[str, Any], samples: list[CompensatorSample],
                     frozen: bool = False) -> tuple[Case, Any]:
    """A case stepping the compensator ``name`` over ``samples`` from a reset (and the compensator)."""
    comp = make_compensator(name, params, AXES, DT_S)
    comp.frozen = frozen
    step = comp.step

    def run() -> int:
        comp.reset()
        for s in samples:
            step(s)
        return len(samples)
    return run, comp


def ilc_update_case(samples: list[CompensatorSample]) -> tuple[Case, Any]:
    """A case timing only the ILC's ``end_run`` after a run over ``samples`` (steps counted: the run's ticks)."""
    run, comp = compensator_case("ilc", {}, samples)
    clock = time.process_time

    def update() -> int:
        run()
        started = clock()
        comp.end_run()
        update.elapsed_s = clock() - started  # type: ignore[attr-defined]  # the bench reads it off the function
        return len(samples)
    return update, comp


def servo_case(samples: list[CompensatorSample]) -> Case:
    """The yardstick: ``ServoController.parts`` (PID, paper 000) on the X errors of ``samples``."""
    servo = ServoController(ServoConfig.from_mapping({"axis_name": "x"}))
    parts = servo.parts
    inputs = [(s.ref_position_m[0], s.position_m[0]) for s in samples]

    def run() -> int:
        for ref, pos in inputs:
            parts(DT_S, ref, 0.08, 0.0, pos, 0.08, 0.0)
        return len(inputs)
    return run


def sklearn_case(samples: list[CompensatorSample]) -> Case:
    """scikit-learn's 8-5-2 ``MLPRegressor.partial_fit`` on one sample per step (SGD, momentum 0.15)."""
    from sklearn.neural_network import MLPRegressor  # heavy import: only when benched

    net = MLPRegressor(hidden_layer_sizes=(5,), activation="tanh", solver="sgd", learning_rate="constant",
                       learning_rate_init=NEURAL["eta"], momentum=0.15, nesterovs_momentum=False, alpha=0.0,
                       batch_size=1, shuffle=False, random_state=0)
    rows = [(np.array([[*s.ref_position_m, *s.position_m, *s.position_m, 0.0, 0.0]]) * 1000.0,
             np.array([s.tracking_error_m]) * 1000.0) for s in samples]
    net.partial_fit(*rows[0])

    def run() -> int:
        for x, y in rows:
            net.partial_fit(x, y)
        return len(rows)
    return run


def measure(cases: dict[str, Case], rounds: int) -> dict[str, list[float]]:
    """CPU µs per step of every case, per round; the cases alternate within each round."""
    costs: dict[str, list[float]] = {name: [] for name in cases}
    clock = time.process_time
    for _ in range(rounds):
        for name, run in cases.items():
            started = clock()
            steps = run()
            elapsed = getattr(run, "elapsed_s", None)
            costs[name].append(((clock() - started) if elapsed is None else elapsed) / steps * 1e6)
    return costs


def build_cases(quick: bool) -> tuple[dict[str, Case], list[Any]]:
    """Every case of the bench, and the compensators that must end without a fault."""
    samples = circle_samples(2000 if quick else 10000)
    neural, neural_comp = compensator_case("neural", NEURAL, samples)
    frozen, _ = compensator_case("neural", NEURAL, samples, frozen=True)
    ccc, _ = compensator_case("ccc", {}, samples)
    ilc_update, ilc_comp = ilc_update_case(samples)
    ilc, ilc_playing = compensator_case("ilc", {}, samples)
    ilc()
    ilc_playing.end_run()  # a learned feedforward: the timed steps play it
    none, _ = compensator_case("none", {}, samples)
    cases = {"servo step (PID)": servo_case(samples), "neural 8-5-2 (forward + learning)": neural,
             "neural 8-5-2 frozen (forward)": frozen, "ccc": ccc, "ilc (during a run)": ilc,
             "ilc end_run (per tick of the run)": ilc_update, "none": none,
             "scikit-learn MLPRegressor.partial_fit 8-5-2": sklearn_case(samples[:len(samples) // 10])}
    return cases, [neural_comp, ilc_comp, ilc_playing]


def compensator_bench(options: argparse.Namespace) -> int:
    """Per-tick cost of each compensator as a ratio to a servo sample, and our network against scikit-learn's."""
    load_before = machine()["load_average_1min"]
    cases, learners = build_cases(options.quick)
    costs = measure(cases, 5 if options.quick else 15)
    for comp in learners:
        if comp.fault is not None:
            raise CncError(f"bench compensator: {comp.fault} (the timing would be of a stopped compensator)")
    median = {name: statistics.median(values) for name, values in costs.items()}
    servo_us = median["servo step (PID)"]
    rows = [[name, round(us, 2), round(us / servo_us, 2)] for name, us in median.items()]
    print(format_table(["per tick", "CPU µs (median)", "/ servo step"], rows))
    ours, theirs = median["neural 8-5-2 (forward + learning)"], median["scikit-learn MLPRegressor.partial_fit 8-5-2"]
    print(f"\n  scikit-learn / ours, one sample forward + backward + update: {theirs / ours:.1f} "
          f"(goal > 1: {goal_text(theirs > ours)})")
    figures = machine()
    print(f"  load average (1 min): {load_before:.2f} before, {figures['load_average_1min']:.2f} after; "
          f"{figures['cpus']} CPUs, Python {figures['python']}")
    write_json(options.json, {"bench": "compensator", "us_per_tick": median, "rounds": costs,
                              "sklearn_over_ours": theirs / ours, "load_average_1min_before": load_before,
                              "machine": figures})
    return 0
