"""The sweep executor: the same engine runs give bit-identical results in-process, in a pool and on a Dask cluster.

The Dask cluster is a LocalCluster bound to 127.0.0.1 only (scheduler, workers, their HTTP servers); the
test checks every socket it opened is on the loopback address and closes the cluster also when a test fails.
"""
from __future__ import annotations

import math
import re
from collections.abc import Iterator
from pathlib import Path

import psutil
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.scoring import contour_error_series
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.executor import DaskExecutor, Executor, ItemError, LocalExecutor, make_executor
from cnc_tools.runs.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[3]
LOOPBACK = "127.0.0.1"


def scenarios() -> list[Scenario]:
    """Four short runs of paper 000's circle (T = 10 ms, 0.3 s), each with its own seed and plant variation."""
    base = load_scenario(ROOT / "scenarios" / "paper000_circle_high.yaml")
    return [base.variant(duration_s=0.3, seed=seed) for seed in (1, 2, 3, 4)]


def fingerprint(record: RunRecord) -> tuple[bytes, bytes, float]:
    """What must agree to the last bit: positions, every axis's commands, the largest contour error [m]."""
    series, _ = contour_error_series(record)
    commands = b"".join(record.commands[axis].command.tobytes() for axis in sorted(record.commands))
    return record.joint_states.position_m.tobytes(), commands, float(series.error_m.max())


def _listening(process: psutil.Process) -> set[tuple[str, int]]:
    return {(c.laddr.ip, c.laddr.port) for c in process.net_connections(kind="inet") if c.status == psutil.CONN_LISTEN}


@pytest.fixture(scope="module")
def loopback_cluster() -> Iterator[str]:
    """A 2-process Dask LocalCluster on 127.0.0.1 only; yields the scheduler address; always closed."""
    from distributed import LocalCluster

    me = psutil.Process()
    before = _listening(me)
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host=LOOPBACK,
                           dashboard_address=f"{LOOPBACK}:0", scheduler_port=0)
    try:
        assert cluster.scheduler_address.startswith(f"tcp://{LOOPBACK}:"), cluster.scheduler_address
        opened = (_listening(me) - before).union(*(_listening(child) for child in me.children(recursive=True)))
        assert opened and {ip for ip, _ in opened} == {LOOPBACK}, opened
        yield cluster.scheduler_address
    finally:
        cluster.close()


@pytest.fixture(scope="module")
def in_process() -> list[tuple[bytes, bytes, float]]:
    with LocalExecutor(1) as executor:
        return [fingerprint(record) for record in executor.map(run_engine, scenarios())]


def test_runs_differ_so_the_order_is_checked(in_process: list[tuple[bytes, bytes, float]]) -> None:
    assert len({peak for _, _, peak in in_process}) == len(in_process)


def test_process_pool_gives_the_in_process_results_bit_for_bit(in_process: list) -> None:
    with LocalExecutor(2) as executor:
        assert [fingerprint(record) for record in executor.map(run_engine, scenarios())] == in_process


def test_dask_cluster_gives_the_in_process_results_bit_for_bit(in_process: list, loopback_cluster: str) -> None:
    with make_executor(scheduler=loopback_cluster) as executor:
        assert isinstance(executor, DaskExecutor)
        assert [fingerprint(record) for record in executor.map(run_engine, scenarios())] == in_process


@pytest.mark.parametrize("kind", ["in-process", "pool", "dask"])
def test_a_failing_item_is_named_with_its_error(kind: str, request: pytest.FixtureRequest) -> None:
    made: dict[str, Executor] = {"in-process": LocalExecutor(1), "pool": LocalExecutor(2)}
    executor = made[kind] if kind in made else DaskExecutor(request.getfixturevalue("loopback_cluster"))
    with executor, pytest.raises(ItemError, match=r"^roots: item 2 failed: ValueError: math domain error") as err:
        executor.map(math.sqrt, [4.0, 9.0, -1.0, 16.0], label="roots")
    assert err.value.index == 2 and isinstance(err.value.__cause__, ValueError)


def test_results_keep_the_order_of_the_items() -> None:
    items = [float(k) for k in range(40, 0, -1)]
    with LocalExecutor(2) as executor:
        assert executor.map(math.sqrt, items) == [math.sqrt(x) for x in items]


@pytest.mark.parametrize("address", ["localhost:8786", "tcp://head", "tcp://head:0", "tcp://head:70000",
                                     "tls://head:8786", "http://127.0.0.1:8787", "tcp://head:8786/x", ""])
def test_a_scheduler_that_is_not_tcp_host_port_is_refused_by_name(address: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(repr(address))):
        make_executor(scheduler=address)


def test_workers_are_checked_and_not_given_with_a_scheduler() -> None:
    with pytest.raises(ConfigError, match="workers must be an integer >= 1, got 0"):
        LocalExecutor(0)
    with pytest.raises(ConfigError, match="workers must not be given with a scheduler"):
        make_executor(workers=2, scheduler="tcp://127.0.0.1:8786")
    assert make_executor().workers >= 1


def test_a_function_workers_cannot_receive_is_refused_in_process_too() -> None:
    with LocalExecutor(1) as executor, pytest.raises(ConfigError, match="fn must be picklable"):
        executor.map(lambda x: x, [1])


def test_a_labelled_map_shows_its_progress_unless_told_not(capsys: pytest.CaptureFixture[str]) -> None:
    with LocalExecutor(1) as executor:  # stderr is not a terminal under capsys: plain lines
        executor.map(math.sqrt, [1.0, 4.0], label="roots")
    with LocalExecutor(1, progress=False) as executor:
        executor.map(math.sqrt, [1.0, 4.0], label="silent")
    lines = capsys.readouterr().err.splitlines()
    assert lines[0].startswith("roots 0/2 · ") and lines[-1].startswith("roots 2/2 · done in "), lines
    assert not [line for line in lines if "silent" in line]
