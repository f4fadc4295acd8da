"""The test session's work units (root conftest.py): each xdist worker on a ROS domain of its own, a graph file
on one."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from cnc_tools.runs.dds import MAX_RANDOM_DOMAIN_ID, claim_free_domain_id

ROOT = Path(__file__).resolve().parents[3]

NOTE = '''
import json, os
from pathlib import Path

def note(name):
    facts = {k: os.environ.get(k) for k in ("PYTEST_XDIST_WORKER", "ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")}
    Path(os.environ["PROBE_OUT"], name + ".json").write_text(json.dumps(facts))
'''
PLAIN = '''
import pytest
from probe_note import note

@pytest.mark.parametrize("i", range(6))
def test_plain(i):
    note(f"plain{i}")
'''
GRAPH = PLAIN.replace("plain", "graph").replace("range(6)", "range(4)")
OTHER_GRAPH = GRAPH.replace("graph", "other")


def test_two_workers_take_two_free_domains_and_one_worker_takes_each_graph_file_whole(tmp_path: Path) -> None:
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    (tmp_path / "probe_note.py").write_text(NOTE)
    (tmp_path / "test_plain.py").write_text(PLAIN)
    (tmp_path / "tests" / "e2e").mkdir(parents=True)
    (tmp_path / "tests" / "e2e" / "test_graph.py").write_text(GRAPH)
    (tmp_path / "tests" / "e2e" / "test_other.py").write_text(OTHER_GRAPH)
    out, locks = tmp_path / "out", tmp_path / "locks"
    out.mkdir()
    # Another session holds all domains but three: the controller and its two workers must take those three.
    held = [claim_free_domain_id(locks) for _ in range(MAX_RANDOM_DOMAIN_ID - 3)]
    free = set(range(1, MAX_RANDOM_DOMAIN_ID + 1)) - {c.domain_id for c in held}
    path = os.pathsep.join([str(ROOT), str(tmp_path), os.environ.get("PYTHONPATH", "")])
    env = {**os.environ, "PROBE_OUT": str(out), "PYTHONPATH": path, "CNC_DOMAIN_LOCK_DIR": str(locks)}
    env.pop("PYTEST_XDIST_WORKER", None)
    try:
        done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "conftest", "-p", "no:cacheprovider",
                               "-n", "2", "--import-mode=importlib", "test_plain.py", "tests/e2e/test_graph.py",
                               "tests/e2e/test_other.py"],
                              cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    finally:
        for claim in held:
            claim.release()
    assert done.returncode == 0, done.stdout + done.stderr
    facts = {p.stem: json.loads(p.read_text()) for p in out.glob("*.json")}
    assert len(facts) == 14
    by_worker = {f["PYTEST_XDIST_WORKER"]: int(f["ROS_DOMAIN_ID"]) for f in facts.values()}
    assert set(by_worker) <= {"gw0", "gw1"}
    assert len(set(by_worker.values())) == len(by_worker) and set(by_worker.values()) <= free, (by_worker, free)
    assert all(f["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" for f in facts.values())
    for name in ("graph", "other"):
        workers = {facts[f"{name}{i}"]["PYTEST_XDIST_WORKER"] for i in range(4)}
        assert len(workers) == 1, (name, workers)
