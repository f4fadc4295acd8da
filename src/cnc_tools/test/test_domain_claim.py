"""Tier 1: a process claims a ROS domain that no other claimant on the host holds (cnc_tools.runs.dds)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from cnc_tools.runs.dds import MAX_RANDOM_DOMAIN_ID, claim_free_domain_id

#: A process that claims a domain from the folder in argv[1], says which, and waits to be killed.
HOLDER = """
import sys, time
from pathlib import Path
from cnc_tools.runs.dds import claim_free_domain_id
claim = claim_free_domain_id(Path(sys.argv[1]))
print(claim.domain_id, flush=True)
time.sleep(600)
"""


def test_claims_are_distinct_until_every_domain_is_taken_and_a_release_gives_one_back(tmp_path: Path) -> None:
    claims = [claim_free_domain_id(tmp_path) for _ in range(MAX_RANDOM_DOMAIN_ID)]
    try:
        assert sorted(c.domain_id for c in claims) == list(range(1, MAX_RANDOM_DOMAIN_ID + 1))
        with pytest.raises(RuntimeError, match=rf"all {MAX_RANDOM_DOMAIN_ID} ROS domains are claimed .*{tmp_path}"):
            claim_free_domain_id(tmp_path)
        given_back = claims.pop(17)
        given_back.release()
        again = claim_free_domain_id(tmp_path)
        claims.append(again)
        assert again.domain_id == given_back.domain_id
    finally:
        for claim in claims:
            claim.release()


def test_another_process_holds_its_claim_until_it_is_killed(tmp_path: Path) -> None:
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(tmp_path)], stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    try:
        held = int(holder.stdout.readline())  # type: ignore[union-attr]  # stdout is a pipe here
        ours = [claim_free_domain_id(tmp_path) for _ in range(MAX_RANDOM_DOMAIN_ID - 1)]
        assert held not in {c.domain_id for c in ours}
        with pytest.raises(RuntimeError, match="are claimed"):
            claim_free_domain_id(tmp_path)
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=10)
    try:
        freed = claim_free_domain_id(tmp_path)  # the kernel dropped the killed holder's flock
        assert freed.domain_id == held
        freed.release()
    finally:
        for claim in ours:
            claim.release()


def test_a_folder_that_cannot_be_made_is_named(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(RuntimeError, match=rf"cannot claim a ROS domain in {blocker / 'locks'}"):
        claim_free_domain_id(blocker / "locks")
