"""An unreachable Dask scheduler is a CncError naming the address and the timeout, raised within the timeout."""
from __future__ import annotations

import socket
import time
from collections.abc import Callable

import pytest

from cnc_contour_control.core.errors import CncError, ConfigError
from cnc_tools.runs.executor import DaskExecutor, Executor, SchedulerUnreachableError, make_executor

LOOPBACK = "127.0.0.1"
TIMEOUT_S = 1.0
#: Connecting may overrun the timeout by Dask's last retry and its event loop's start; far less than a hang.
SLACK_S = 10.0


def closed_port() -> int:
    """A port on 127.0.0.1 that nothing listens on (bound, read, closed)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind((LOOPBACK, 0))
        return int(probe.getsockname()[1])


def _dask(address: str) -> Executor:
    return DaskExecutor(address, timeout_s=TIMEOUT_S)


def _made(address: str) -> Executor:
    return make_executor(scheduler=address, timeout_s=TIMEOUT_S)


@pytest.mark.parametrize("build", [_dask, _made], ids=["DaskExecutor", "make_executor"])
def test_an_unreachable_scheduler_is_a_cnc_error_naming_address_and_timeout(build: Callable[[str], Executor]) -> None:
    address = f"tcp://{LOOPBACK}:{closed_port()}"
    start = time.perf_counter()
    with pytest.raises(SchedulerUnreachableError) as caught:
        build(address)
    elapsed_s = time.perf_counter() - start
    assert isinstance(caught.value, CncError)
    assert address in str(caught.value) and f"timeout_s={TIMEOUT_S:g} s" in str(caught.value)
    assert isinstance(caught.value.__cause__, OSError)  # the original error is kept, not shown bare
    assert TIMEOUT_S * 0.5 <= elapsed_s < TIMEOUT_S + SLACK_S, elapsed_s


@pytest.mark.parametrize("timeout_s", [0.0, -1.0, float("nan")])
def test_a_timeout_that_is_not_positive_is_refused_by_name(timeout_s: float) -> None:
    with pytest.raises(ConfigError, match="timeout_s must be a number > 0"):
        DaskExecutor(f"tcp://{LOOPBACK}:{closed_port()}", timeout_s=timeout_s)
