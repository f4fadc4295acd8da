"""Session-wide test setup: DDS on loopback, a ROS domain of its own per test process, and the work units.

At the end the controller removes the Fast DDS shared-memory segments that
the session's killed nodes left in ``/dev/shm`` (:mod:`cnc_tools.runs.shm`).

With pytest-xdist (``-n auto``, pytest.ini: one worker more than the cores,
:func:`pytest_xdist_auto_num_workers`) every worker is a session of its
own. Each process of the session (controller and workers) claims a domain that
no other claimant on this host holds (:func:`cnc_tools.runs.dds.claim_free_domain_id`,
an flock the kernel drops when the process ends), so no two workers share one,
nor two test sessions running at once (two clones, a developer beside CI):
with independent random draws two sessions shared a domain 3 % of the time,
and their fixed-namespace tests (``/cnc``) heard each other. A test file is
one work unit: its tests run one after the other on one worker, so a module
fixture (a bench's runs, a recorded bag) is made once, and a worker runs at
most one whole graph (``tests/e2e``) at a time.
"""
from __future__ import annotations

import atexit
import functools
import importlib.util
import os
import tempfile
from collections.abc import Generator
from pathlib import Path

import pytest
from hypothesis import settings

#: A falsified property prints the blob that replays its case exactly (numpy's repr of an array rounds to 8
#: digits, so the printed example alone may not fail again). The test command draws the same examples on every run
#: (``derandomize``): a landing fails on a change, not on the day's draw. ``CNC_HYPOTHESIS=explore`` draws new ones
#: (how the generated cases pinned as ``@example`` were found).
settings.register_profile("cnc", print_blob=True, derandomize=True)
settings.register_profile("explore", print_blob=True)
settings.load_profile("explore" if os.environ.get("CNC_HYPOTHESIS") == "explore" else "cnc")

#: The Fast DDS segments present when the session began (the controller's; None in a worker).
SEGMENTS_BEFORE = pytest.StashKey[set]()
#: This process's claim on its domain, held open for the process's life.
DOMAIN_CLAIMS: list[object] = []
#: A second domain for this process, where no other participant of the process lives (test_parameters' many
#: short-lived nodes): one of the domains Linux allows beyond the claimed 1..100 (ports up to 65 4xx). Another
#: process may share it; what must not meet is participants inside one process.
QUIET_DOMAIN_ENV = "CNC_QUIET_DOMAIN_ID"
QUIET_DOMAINS = range(215, 233)


def pytest_configure(config: pytest.Config) -> None:
    """Before any node exists: the loopback DDS policy and this session's own domain (and the tier check, if on)."""
    from cnc_tools.runs.dds import apply_loopback_policy, claim_free_domain_id

    if os.environ.get(TIER_CHECK):
        start_tier_check()
    one_blas_thread()

    claim = claim_free_domain_id()
    DOMAIN_CLAIMS.append(claim)
    apply_loopback_policy(os.environ, claim.domain_id)
    os.environ[QUIET_DOMAIN_ENV] = str(QUIET_DOMAINS[0] + claim.domain_id % len(QUIET_DOMAINS))
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        from cnc_tools.runs.shm import fast_dds_segments

        config.stash[SEGMENTS_BEFORE] = fast_dds_segments()


#: Threads of the BLAS (OpenBLAS) in every test process and the processes it starts.
BLAS_THREADS = 1


def one_blas_thread() -> None:
    """One BLAS thread per process: the session already runs a process per core and one more, so a BLAS
    thread pool per worker only spins against the other worker (a 7680 x 68 least squares: 0.31 s wall, 0.16 s
    CPU with the default pool on 2 busy cores, 0.012 s with one thread). Children inherit the environment;
    this process's numpy, already loaded (plugins import it), is limited through threadpoolctl."""
    from threadpoolctl import threadpool_limits

    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(name, str(BLAS_THREADS))
    threadpool_limits(limits=BLAS_THREADS)


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter, config: pytest.Config) -> None:
    """The controller, once every worker ended: remove the stale segments this session made, and say how many."""
    if SEGMENTS_BEFORE not in config.stash:
        return
    from cnc_tools.runs.shm import remove_stale_segments

    removed = remove_stale_segments(config.stash[SEGMENTS_BEFORE])
    if removed:
        terminalreporter.write_line(f"removed {len(removed)} stale Fast DDS shared-memory segments that killed nodes "
                                    "of this session left in /dev/shm")


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto``: one worker more than the cores. About a third of a worker's time is spent waiting on node
    processes (a graph starting, a deadline), which a third worker fills on two cores: the whole suite 11 min 6 s
    against 13 min 3 s with two workers, same clone, one after the other at load 5-10."""
    return (os.cpu_count() or 1) + 1


def graph_lane_scope(nodeid: str) -> str:
    """The xdist work unit of a test: its file (module fixtures are made once per worker that runs them)."""
    return nodeid.split("::", 1)[0]


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object:
    """Scope scheduling with :func:`graph_lane_scope` (xdist's own ``loadgroup`` misses pytest 9's node ids).

    Units go out in collection order, the whole-graph files first (the longest ones), each to whichever worker is
    free.
    """
    from xdist.scheduler import LoadScopeScheduling

    config.option.loadscopereorder = False  # collection order (the graph files first), not the test count

    class GraphLaneScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return graph_lane_scope(nodeid)

    return GraphLaneScheduling(config, log)


#: The whole-graph tests (node ids as the controller sees them): the longest files, run first.
GRAPH_TESTS = "tests/e2e/"


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The whole-graph files first, so no long graph test is left for the end of a run on two workers."""
    items.sort(key=lambda item: not item.nodeid.startswith(GRAPH_TESTS))



#: ``CNC_TIER_CHECK=1 ./dev test -m "not nodes and not e2e"``: every core-tier test (marked neither ``nodes`` nor
#: ``e2e``) that starts a DDS participant, in the test process or in any Python process it starts, fails and says
#: which process did. Off unless set by hand: it puts :data:`TIER_CHECK_DIR` on every process's ``PYTHONPATH``.
TIER_CHECK = "CNC_TIER_CHECK"
TIER_CHECK_DIR = Path(__file__).parent / "tests" / "tier_check"
#: The file the processes of the running test append their participants to (read by ``tier_check/sitecustomize.py``).
PARTICIPANT_LOG = "CNC_PARTICIPANT_LOG"


def start_tier_check() -> None:
    """Note participants in this process now and in every Python process started from here on."""
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(TIER_CHECK_DIR), os.environ.get("PYTHONPATH")]))
    spec = importlib.util.spec_from_file_location("cnc_tier_check", TIER_CHECK_DIR / "sitecustomize.py")
    assert spec is not None and spec.loader is not None, TIER_CHECK_DIR
    spec.loader.exec_module(importlib.util.module_from_spec(spec))


@functools.cache
def participant_log_dir() -> Path:
    """A directory of this process's own for the participant logs (removed at exit)."""
    made = tempfile.TemporaryDirectory(prefix="cnc_tier_check_")
    atexit.register(made.cleanup)
    return Path(made.name)


def is_core_tier(item: pytest.Item) -> bool:
    """A test of the core tier: marked neither ``nodes`` nor ``e2e``."""
    return item.get_closest_marker("nodes") is None and item.get_closest_marker("e2e") is None


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    """Under the tier check: a participant log of the core-tier test's own, before its fixtures are made."""
    if os.environ.get(TIER_CHECK) and is_core_tier(item):
        log = participant_log_dir() / "participants.log"
        log.unlink(missing_ok=True)
        os.environ[PARTICIPANT_LOG] = str(log)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> Generator[None, None, None]:
    """Under the tier check: fail the core-tier test whose setup, call or teardown started a participant."""
    yield
    log = os.environ.pop(PARTICIPANT_LOG, None)
    if log is not None and Path(log).exists():
        started = Path(log).read_text(encoding="utf-8")
        Path(log).unlink()
        pytest.fail(f"a core-tier test started DDS participants (mark it nodes or e2e):\n{started}", pytrace=False)


@pytest.fixture(autouse=True)
def _no_progress_task_left_open() -> Generator[None, None, None]:
    """Each test starts with no progress task open: a bench that raised inside ``track`` leaves its task open until
    its generator is collected (the traceback pytest keeps holds it), and the next test's lines would nest in it."""
    from cnc_tools.runs.progress import reporter

    reporter().tasks.clear()
    yield


#: ``CNC_TEST_CPU_LOG=FILE ./dev test``: each test appends ``cpu_s wall_s nodeid`` to FILE, the CPU its worker and
#: the worker's reaped child processes (node processes, benches' subprocesses) spent on setup, call and teardown:
#: what to cut first when the suite is slow, measured the same on a loaded machine as on a quiet one.
CPU_LOG = "CNC_TEST_CPU_LOG"


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Generator[None, None, object]:
    """Under :data:`CPU_LOG`: the test's CPU and wall time, a line each."""
    path = os.environ.get(CPU_LOG)
    if not path:
        return (yield)
    import resource
    import time

    def cpu_s() -> float:
        own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime

    cpu0, wall0 = cpu_s(), time.monotonic()
    result = yield
    with open(path, "a", encoding="utf-8") as log:
        log.write(f"{cpu_s() - cpu0:.2f} {time.monotonic() - wall0:.2f} {item.nodeid}\n")
    return result
