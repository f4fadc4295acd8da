"""Session-wide test setup: DDS on loopback, a fresh random ROS domain per test session, and the work units.

With pytest-xdist (``-n 2``, pytest.ini) every worker is a session of its
own: the controller draws a random domain and each worker takes the next ones
(``gw0`` the first after it, ...), so no two workers share one. A whole-graph
test file (``tests/e2e/*.py``) is one work unit: its tests run one after the
other on one worker (they share module fixtures and namespaces), so a worker
runs at most one graph at a time; the other tests are spread one by one.
"""
from __future__ import annotations

import os

import pytest

#: Where the controller leaves its domain for the workers it starts.
DOMAIN_BASE_KEY = "CNC_TEST_DOMAIN_BASE"
#: Where the whole-graph tests live (node ids as the controller sees them).
GRAPH_TESTS = "tests/e2e/"


def session_domain_id(environ: dict[str, str] | os._Environ[str], draw: int) -> int:
    """This session's domain: ``draw`` for the controller (or a run without xdist), base + 1 + worker index else."""
    from cnc_tools.runs.dds import MAX_RANDOM_DOMAIN_ID

    worker, base = environ.get("PYTEST_XDIST_WORKER", ""), environ.get(DOMAIN_BASE_KEY, "")
    if not worker.startswith("gw") or not base:
        return draw
    return 1 + (int(base) + int(worker[2:])) % MAX_RANDOM_DOMAIN_ID


def pytest_configure(config: pytest.Config) -> None:
    """Before any node exists: the loopback DDS policy and this session's own domain."""
    from cnc_tools.runs.dds import apply_loopback_policy, random_domain_id

    domain_id = session_domain_id(os.environ, random_domain_id())
    os.environ.setdefault(DOMAIN_BASE_KEY, str(domain_id))
    apply_loopback_policy(os.environ, domain_id)


def graph_lane_scope(nodeid: str) -> str:
    """The xdist work unit of a test: its file for a whole-graph test, the test itself else."""
    return nodeid.split("::", 1)[0] if nodeid.startswith(GRAPH_TESTS) else nodeid


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object:
    """Scope scheduling with :func:`graph_lane_scope` (xdist's own ``loadgroup`` misses pytest 9's node ids).

    The graph files are the largest units, so they go out first and run beside the rest from the start.
    """
    from xdist.scheduler import LoadScopeScheduling

    class GraphLaneScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return graph_lane_scope(nodeid)

    return GraphLaneScheduling(config, log)
