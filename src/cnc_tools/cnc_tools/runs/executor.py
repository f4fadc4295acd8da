"""One interface for many independent runs: in this process, a local process pool, or a Dask cluster.

Sweeps (seed sweeps of the benches, tuning by simulated tests) run many
engine runs that share nothing. :meth:`Executor.map` runs ``fn`` on every item
and returns the results in the order of the items, whatever the order they
finish in, so a sweep gives the same results on 1 process, ``n`` processes or
a cluster (each run is deterministic on its own: its seed is in its scenario).

- :class:`LocalExecutor` (the default): a :class:`~concurrent.futures.ProcessPoolExecutor`
  of ``workers`` processes, all cores unless told; ``workers=1`` runs in this
  process without a pool. Workers are *spawned* (a fresh interpreter), never
  forked: a fork copies the parent's threads' memory without the threads, so a
  ROS 2 / DDS participant (its discovery threads, sockets, shared-memory
  segments) or any lock held at fork time would be copied half-alive into the
  child. The engine itself imports no rclpy (``test_core_purity`` checks it), but
  a sweep may be started from a process that has a node; "spawn" is also the
  one start method every platform has ("forkserver" is Unix-only).
- :class:`DaskExecutor`: ``distributed.Client(scheduler)``, ``client.map`` then
  ``client.gather``; the workers must have this suite installed (the function
  is pickled by reference, as for the pool). The scheduler address must be
  ``tcp://host:port``.

Both pickle ``fn`` and the items (so ``fn`` is a module-level function, not a
lambda or a closure); the in-process executor checks that too, so a sweep that
works with one worker works with many. A failure in one item raises
:class:`ItemError` naming the item's index and the original error (chained as
``__cause__``), and the items not yet started are cancelled. A labelled map is
a task of the process's progress reporter (:mod:`cnc_tools.runs.progress`:
``label done/total``, elapsed and estimate on stderr; ``--quiet`` silences it),
unless the executor was made with ``progress=False``.

Use :func:`make_executor` in a ``with`` block so pools and clients are closed::

    with make_executor(workers=None, scheduler=args.scheduler) as executor:
        records = executor.map(run_engine, scenarios, label="seeds")
"""
from __future__ import annotations

import multiprocessing
import os
import pickle
import re
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from types import TracebackType
from typing import Any, Protocol, TypeVar

from cnc_contour_control.core.errors import CncError, ConfigError
from cnc_tools.runs.progress import task as progress_task

__all__ = ["DaskExecutor", "Executor", "ItemError", "LocalExecutor", "SCHEDULER_PATTERN", "SchedulerUnreachableError",
           "check_scheduler", "make_executor"]

T = TypeVar("T")
R = TypeVar("R")

#: Start method of the pool's workers (see the module docstring: never fork a process that may hold DDS state).
START_METHOD = "spawn"
#: A Dask scheduler address: ``tcp://`` host name, IPv4 or bracketed IPv6, ``:`` port.
SCHEDULER_PATTERN = re.compile(r"tcp://(?P<host>[A-Za-z0-9.\-]+|\[[0-9A-Fa-f:.]+\]):(?P<port>\d{1,5})")


class ItemError(CncError, RuntimeError):
    """Item ``index`` of a :meth:`Executor.map` raised; the original error is ``__cause__`` (and ``cause``)."""

    def __init__(self, index: int, cause: BaseException, label: str = "") -> None:
        where = f"{label}: " if label else ""
        super().__init__(f"{where}item {index} failed: {type(cause).__name__}: {cause}")
        self.index = index
        self.cause = cause


class SchedulerUnreachableError(CncError, ConnectionError):
    """No Dask scheduler answered at ``address`` within ``timeout_s``; the connection error is ``__cause__``."""

    def __init__(self, address: str, timeout_s: float, cause: BaseException) -> None:
        super().__init__(f"Dask scheduler {address} is unreachable: no answer within timeout_s={timeout_s:g} s "
                         f"({type(cause).__name__}: {cause}); check the address and that the scheduler runs")
        self.address = address
        self.timeout_s = timeout_s


class Executor(Protocol):
    """Runs a picklable function on independent items; a context manager that closes what it opened."""

    def map(self, fn: Callable[[T], R], items: Sequence[T], *, label: str = "") -> list[R]:
        """``[fn(item) for item in items]``, computed where the executor runs things, in the order of ``items``.

        Raises
        ------
        ItemError
            When ``fn`` raised on an item: names the item's index and the original error.
        """
        ...

    def close(self) -> None:
        """Release workers, pools and connections (idempotent)."""
        ...

    def __enter__(self) -> Executor: ...

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None: ...


class _Progress:
    """A labelled map's task on the process's progress reporter; none without a label or an item, or with
    ``enabled=False``."""

    def __init__(self, label: str, total: int, enabled: bool | None) -> None:
        self.task = progress_task(label, total) if label and total and enabled is not False else None

    def step(self) -> None:
        """One more item done."""
        if self.task is not None:
            self.task.step()

    def __enter__(self) -> _Progress:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        if self.task is not None:
            self.task.close(stopped=kind is not None)


class _Closing:
    """The context-manager half of :class:`Executor`."""

    def close(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def __enter__(self) -> Any:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.close()


def _require_picklable(fn: Callable[..., Any], items: Iterable[Any], label: str) -> None:
    """Refuse what a worker process could not receive, naming it."""
    for what, value in (("fn", fn), *((f"item {i}", item) for i, item in enumerate(items))):
        try:
            pickle.dumps(value)
        except (pickle.PicklingError, TypeError, AttributeError) as err:
            where = f"{label}: " if label else ""
            raise ConfigError(f"{where}{what} must be picklable (a module-level function, plain data), "
                              f"got {value!r}: {err}") from err


class LocalExecutor(_Closing):
    """A pool of ``workers`` spawned processes on this machine; ``workers=1`` runs in this process.

    Parameters
    ----------
    workers : int or None
        Processes; None: all cores (``os.cpu_count()``). Must be >= 1.
    progress : bool or None
        False: no progress; else labelled maps are tasks of the process's reporter (:mod:`cnc_tools.runs.progress`).
    """

    def __init__(self, workers: int | None = None, *, progress: bool | None = None) -> None:
        count = (os.cpu_count() or 1) if workers is None else workers
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise ConfigError(f"workers must be an integer >= 1, got {workers!r}")
        self.workers = count
        self.progress = progress
        self._pool: ProcessPoolExecutor | None = None

    def map(self, fn: Callable[[T], R], items: Sequence[T], *, label: str = "") -> list[R]:
        """See :meth:`Executor.map`; the pool starts at the first map with more than one item and is reused."""
        items = list(items)
        _require_picklable(fn, items, label)
        with _Progress(label, len(items), self.progress) as progress:
            if self.workers == 1 or len(items) <= 1:
                return [self._one(fn, index, item, label, progress) for index, item in enumerate(items)]
            return self._pooled(fn, items, label, progress)

    @staticmethod
    def _one(fn: Callable[[T], R], index: int, item: T, label: str, progress: _Progress) -> R:
        try:
            result = fn(item)
        except Exception as err:
            raise ItemError(index, err, label) from err
        progress.step()
        return result

    def _pooled(self, fn: Callable[[T], R], items: list[T], label: str, progress: _Progress) -> list[R]:
        if self._pool is None:
            context = multiprocessing.get_context(START_METHOD)
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=context)
        futures: dict[Future[R], int] = {self._pool.submit(fn, item): index for index, item in enumerate(items)}
        results: list[Any] = [None] * len(items)
        try:
            for future in as_completed(futures):
                index = futures[future]
                error = future.exception()
                if error is not None:
                    raise ItemError(index, error, label) from error
                results[index] = future.result()
                progress.step()
        finally:
            for future in futures:
                future.cancel()
        return results

    def close(self) -> None:
        """Shut the pool down (waits for running items, cancels queued ones)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def check_scheduler(address: str) -> str:
    """``address`` if it is ``tcp://host:port`` with a port in 1..65535; else a ConfigError naming it."""
    found = SCHEDULER_PATTERN.fullmatch(address) if isinstance(address, str) else None
    if found is None or not 1 <= int(found["port"]) <= 65535:
        raise ConfigError(f"scheduler must be an address tcp://host:port (port 1..65535), got {address!r}")
    return address


def _raise_item_error(future: Any, index: int, label: str) -> None:
    """Raise the :class:`ItemError` of a Dask future that did not finish (it raised, or was cancelled)."""
    try:
        future.result()
    except Exception as err:
        raise ItemError(index, err, label) from err
    raise ItemError(index, RuntimeError(f"task ended as {future.status!r}"), label)


class DaskExecutor(_Closing):
    """Runs items on a Dask distributed cluster through ``distributed.Client(scheduler)``.

    Parameters
    ----------
    scheduler : str
        The scheduler's address, ``tcp://host:port`` (e.g. ``tcp://10.0.0.5:8786``).
    timeout_s : float
        How long to wait for the scheduler when connecting [s], > 0.
    progress : bool or None
        As for :class:`LocalExecutor`.

    Raises
    ------
    SchedulerUnreachableError
        No scheduler answered at ``scheduler`` within ``timeout_s`` (names both).
    """

    def __init__(self, scheduler: str, *, timeout_s: float = 30.0, progress: bool | None = None) -> None:
        from distributed import Client  # loaded only when a cluster is used

        self.scheduler = check_scheduler(scheduler)
        if isinstance(timeout_s, bool) or not isinstance(timeout_s, (int, float)) or not timeout_s > 0:
            raise ConfigError(f"timeout_s must be a number > 0, got {timeout_s!r}")
        self.progress = progress
        try:
            self._client: Any = Client(self.scheduler, timeout=timeout_s, set_as_default=False)
        except OSError as err:  # distributed raises OSError (TimeoutError among them) for a scheduler it cannot reach
            raise SchedulerUnreachableError(self.scheduler, timeout_s, err) from err

    def map(self, fn: Callable[[T], R], items: Sequence[T], *, label: str = "") -> list[R]:
        """See :meth:`Executor.map`: ``client.map`` (each item its own task), then ``client.gather``."""
        from distributed import as_completed as dask_completed

        items = list(items)
        if not items:
            return []
        futures = self._client.map(fn, items, pure=False)
        index = {future.key: i for i, future in enumerate(futures)}
        try:
            with _Progress(label, len(items), self.progress) as progress:
                for future in dask_completed(futures, loop=self._client.loop):
                    if future.status != "finished":
                        _raise_item_error(future, index[future.key], label)
                    progress.step()
            return list(self._client.gather(futures))
        finally:
            self._client.cancel(futures)

    def close(self) -> None:
        """Close the client (the cluster itself keeps running: it is not ours)."""
        if self._client is not None:
            self._client.close()
            self._client = None


def make_executor(workers: int | None = None, scheduler: str | None = None, *,
                  progress: bool | None = None, timeout_s: float = 30.0) -> Executor:
    """The sweep's executor: a :class:`DaskExecutor` when ``scheduler`` is given, else a :class:`LocalExecutor`.

    Parameters
    ----------
    workers : int or None
        Local processes (None: all cores); not with ``scheduler`` (the cluster's workers are its own).
    scheduler : str or None
        A Dask scheduler address ``tcp://host:port``.
    progress : bool or None
        False: no progress; else labelled maps show on stderr (:mod:`cnc_tools.runs.progress`).
    timeout_s : float
        How long to wait for the scheduler when connecting [s] (:class:`SchedulerUnreachableError` after it).
    """
    if scheduler is None:
        return LocalExecutor(workers, progress=progress)
    if workers is not None:
        raise ConfigError(f"workers must not be given with a scheduler (the cluster's workers run the items), "
                          f"got workers={workers} and scheduler={scheduler!r}")
    return DaskExecutor(scheduler, progress=progress, timeout_s=timeout_s)
