"""Sweeps of the paper-000 benches: cases × controllers × seeds, run and scored, then summarised.

A sweep runs every (case, controller, seed) once. The first ``graph_seeds``
seeds go through the node graph (recorded, scored from the bag); the rest run
in the engine. Where a run went through the graph, the engine runs it too and
the sweep keeps the largest difference of the two scores (they should agree:
same cores, same tick order, same scorer).
"""
from __future__ import annotations

import argparse
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.scoring import Score
from cnc_tools.reproductions.paper000.data import TABLE5
from cnc_tools.reproductions.paper000.runs import (
    Controller,
    RunScore,
    engine_recorded_run,
    get_controller,
    graph_recorded_run,
    run_and_score,
    scenario_for,
)
from cnc_tools.run_record import RecordedRun
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.progress import task as progress_task


@dataclass(frozen=True)
class Case:
    """A scenario file under a short name (``line_low``, ``line27``, ...)."""

    name: str
    path: Path
    overrides: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SweepPlan:
    """What a sweep runs: seeds, and how many of the first go through the node graph."""

    seeds: tuple[int, ...]
    graph_seeds: int
    out_dir: Path


@dataclass
class Sweep:
    """Scores by (case, controller), one per seed in seed order; the first seed's runs kept for plots."""

    scores: dict[tuple[str, str], list[RunScore]] = field(default_factory=dict)
    first_runs: dict[tuple[str, str], dict[str, tuple[RecordedRun, Score]]] = field(default_factory=dict)
    graph_vs_engine_blu: list[float] = field(default_factory=list)

    def values(self, case: str, controller: str, metric: str, view: str = "paper") -> list[float]:
        """Per-seed ``metric`` (``max``/``rms``) [BLU] under ``view``."""
        return [getattr(s, f"{metric}_blu")[view] for s in self.scores[(case, controller)]]

    def mean(self, case: str, controller: str, metric: str, view: str = "paper") -> float:
        """Mean over seeds [BLU]."""
        return statistics.fmean(self.values(case, controller, metric, view))

    def to_json(self) -> list[dict[str, Any]]:
        """Every run's scores as plain data."""
        return [asdict(s) for runs in self.scores.values() for s in runs]


def run_sweep(cases: Sequence[Case], controllers: Sequence[str], plan: SweepPlan, sweep: Sweep | None = None,
              lookup: Mapping[str, Controller] | None = None) -> Sweep:
    """Run every case × controller × seed of ``plan`` into ``sweep`` (a new one if None).

    Controllers are looked up by name in ``lookup`` (default ``CONTROLLERS``).
    """
    sweep = sweep if sweep is not None else Sweep()
    with progress_task("paper000 runs", len(cases) * len(controllers) * len(plan.seeds)) as runs:
        for case in cases:
            for name in controllers:
                controller = lookup[name] if lookup is not None else get_controller(name)
                for k, seed in enumerate(plan.seeds):
                    graph = k < plan.graph_seeds
                    if graph:
                        print(f"  node graph: {case.name} {name} seed {seed} ...", flush=True)
                    _one(sweep, case, controller, seed, graph, plan.out_dir)
                    runs.step(note=f"{case.name} {name} seed {seed}")
    return sweep


def _one(sweep: Sweep, case: Case, controller: Controller, seed: int, graph: bool, out_dir: Path) -> None:
    name = controller.name
    scenario = scenario_for(case.path, controller, seed, case.overrides)
    engine_score, engine_runs = run_and_score(scenario, name, seed, "engine", engine_recorded_run)
    score, runs = engine_score, engine_runs
    if graph:
        run_dir = out_dir / "runs" / case.name / name.replace(":", "_") / f"seed{seed}"
        score, runs = run_and_score(scenario, name, seed, "graph", lambda s: graph_recorded_run(s, run_dir))
        sweep.graph_vs_engine_blu.append(max(
            abs(getattr(score, f"{m}_blu")[v] - getattr(engine_score, f"{m}_blu")[v])
            for m in ("max", "rms") for v in score.max_blu))
    sweep.scores.setdefault((case.name, name), []).append(score)
    sweep.first_runs.setdefault((case.name, name), runs)


def mean_spread(values: Sequence[float]) -> tuple[float, float]:
    """Mean and sample standard deviation (0 for one value)."""
    return statistics.fmean(values), (statistics.stdev(values) if len(values) > 1 else 0.0)


def stat_text(values: Sequence[float]) -> str:
    """``mean ± spread`` with two decimals, BLU."""
    mean, spread = mean_spread(values)
    return f"{mean:.2f} ± {spread:.2f}"


def wins(better: Sequence[float], worse: Sequence[float]) -> str:
    """In how many seeds ``better`` <= ``worse`` (paired by seed), as ``k/n``."""
    return f"{sum(b <= w for b, w in zip(better, worse))}/{len(better)}"


# =========================================================================== bench settings
@dataclass(frozen=True)
class Settings:
    """Options of one bench run."""

    quick: bool
    engine: bool
    seeds: tuple[int, ...]
    out_dir: Path
    json: Path | None

    def plan(self, graph_seeds: int) -> SweepPlan:
        """Sweep plan: the first ``graph_seeds`` seeds through the node graph (none with ``--engine``)."""
        return SweepPlan(self.seeds, 0 if self.engine else graph_seeds, self.out_dir)


def settings_of(options: argparse.Namespace, default_seeds: int) -> Settings:
    """Settings from the bench options (``engine``/``seeds`` may be missing: defaults then)."""
    quick = bool(getattr(options, "quick", False))
    count = getattr(options, "seeds", None)
    count = 1 if quick and count is None else (default_seeds if count is None else count)
    if int(count) != count or count < 1:
        raise ConfigError(f"seeds must be an integer >= 1, got {count!r}")
    out = getattr(options, "out", None) or project_root() / "bags" / "bench" / options.name / timestamp()
    return Settings(quick, bool(getattr(options, "engine", False)), tuple(range(1, int(count) + 1)), Path(out),
                    getattr(options, "json", None))


def table5_cases(quick: bool) -> list[Case]:
    """The Table 5 scenarios (``--quick``: line_low only)."""
    rows = TABLE5[:1] if quick else TABLE5
    return [Case(row.case, project_root() / row.scenario) for row in rows]
