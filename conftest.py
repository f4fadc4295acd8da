"""Session-wide test setup: DDS on loopback, a ROS domain of its own per test process, and the work units.

At the end the controller removes the Fast DDS shared-memory segments that
the session's killed nodes left in ``/dev/shm`` (:mod:`cnc_tools.runs.shm`).

With pytest-xdist (``-n 2``, pytest.ini) every worker is a session of its
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

import os

import pytest

#: The Fast DDS segments present when the session began (the controller's; None in a worker).
SEGMENTS_BEFORE = pytest.StashKey[set]()
#: This process's claim on its domain, held open for the process's life.
DOMAIN_CLAIMS: list[object] = []


def pytest_configure(config: pytest.Config) -> None:
    """Before any node exists: the loopback DDS policy and this session's own domain."""
    from cnc_tools.runs.dds import apply_loopback_policy, claim_free_domain_id

    claim = claim_free_domain_id()
    DOMAIN_CLAIMS.append(claim)
    apply_loopback_policy(os.environ, claim.domain_id)
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        from cnc_tools.runs.shm import fast_dds_segments

        config.stash[SEGMENTS_BEFORE] = fast_dds_segments()


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter, config: pytest.Config) -> None:
    """The controller, once every worker ended: remove the stale segments this session made, and say how many."""
    if SEGMENTS_BEFORE not in config.stash:
        return
    from cnc_tools.runs.shm import remove_stale_segments

    removed = remove_stale_segments(config.stash[SEGMENTS_BEFORE])
    if removed:
        terminalreporter.write_line(f"removed {len(removed)} stale Fast DDS shared-memory segments that killed nodes "
                                    "of this session left in /dev/shm")


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

