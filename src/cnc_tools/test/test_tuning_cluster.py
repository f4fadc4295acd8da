"""The tuner on the suite's executor: one search gives the same bits in-process, in a pool and on Dask.

Differential evolution evaluates a whole generation at once (``updating="deferred"``) through
``executor.map``; the results come back in the population's order, so the search, its history and its
optimum must not depend on where the members were evaluated. The Dask cluster is a LocalCluster bound to
127.0.0.1 (scheduler, workers and dashboard), closed also when a test fails.
"""
from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from scipy.optimize import rosen

from cnc_tools.cli.main import main
from cnc_tools.runs.executor import DaskExecutor, LocalExecutor, make_executor
from cnc_tools.runs.folders import project_root
from cnc_tools.tuning.problem import DesignVariable
from cnc_tools.tuning.solve import TuningResult, solve

LOOPBACK = "127.0.0.1"
VARIABLES = (DesignVariable("a", -3.0, 3.0), DesignVariable("b", -3.0, 3.0), DesignVariable("c", -3.0, 3.0))
PAPER003 = project_root() / "scenarios" / "paper003_circle.yaml"


@pytest.fixture(scope="module")
def scheduler() -> Iterator[str]:
    """A 2-worker Dask LocalCluster on 127.0.0.1 only; yields its scheduler address."""
    from distributed import LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host=LOOPBACK,
                           dashboard_address=f"{LOOPBACK}:0", scheduler_port=0)
    try:
        assert cluster.scheduler_address.startswith(f"tcp://{LOOPBACK}:"), cluster.scheduler_address
        yield cluster.scheduler_address
    finally:
        cluster.close()


def search(executor: LocalExecutor | DaskExecutor | None) -> TuningResult:
    """SciPy's Rosenbrock function in three variables: 4 generations of 12 members."""
    return solve(rosen, VARIABLES, maxiter=4, popsize=4, seed=7, executor=executor)


def same_bits(left: TuningResult, right: TuningResult) -> bool:
    """Optimum, objective, per-generation history and evaluation count equal to the last bit."""
    return (left.x, left.objective, left.history, left.evaluations) == (
        right.x, right.objective, right.history, right.evaluations)


def test_the_search_is_bit_equal_in_process_in_a_pool_and_on_dask(scheduler: str) -> None:
    alone = search(None)
    assert len(alone.history) == 4 and alone.history[-1] < alone.history[0]  # it searched: the figure moved
    with LocalExecutor(1) as executor:
        assert same_bits(search(executor), alone)
    with LocalExecutor(2) as executor:
        assert same_bits(search(executor), alone)
    with make_executor(scheduler=scheduler) as executor:
        assert isinstance(executor, DaskExecutor)
        assert same_bits(search(executor), alone)


def test_cli_tune_on_a_scheduler_writes_the_in_process_result(scheduler: str, tmp_path: Path) -> None:
    """``cnc-contour tune --scheduler``: the same result.json as ``--workers 1`` (paper 003's analytic Eq. 17)."""
    common = ["tune", str(PAPER003), "--var", "plant.axis_overrides.*.ki=10:100",
              "--var", "plant.axis_overrides.*.kp=0.1:2.6", "--maxiter", "3", "--popsize", "3", "--seed", "1"]
    assert main([*common, "--workers", "1", "--out", str(tmp_path / "alone")]) == 0
    assert main([*common, "--scheduler", scheduler, "--out", str(tmp_path / "dask")]) == 0
    alone, dask = (json.loads((tmp_path / name / "result.json").read_text()) for name in ("alone", "dask"))
    assert alone["evaluations"] == dask["evaluations"] > 0
    assert (alone["optimum"], alone["objective"], alone["history"]) == (dask["optimum"], dask["objective"],
                                                                         dask["history"])
