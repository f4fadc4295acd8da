"""Tier 3: the README's "By hand" start works as written and gives the runner's run.

The commands are read from the README's ``### By hand`` block and started as
a user starts them from ``./dev shell`` (every executable on PATH, one
domain: this session's, in the installed config folder), in reverse order
(the README says any order works: every stage waits for the recorder), the
bag moved into the test's folder. The plant must finish, the recorder close a complete bag, and
the recorded run must be the engine's run of the same scenario to 1e-9: the
installed parameters file is the runner's.
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
from pathlib import Path

import numpy as np
import pytest

from cnc_contour_control.testing import stop_processes
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.outputs import judge_bag
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
README_BAG = "/tmp/by_hand_bag"
pytestmark = pytest.mark.e2e


def by_hand_commands() -> list[list[str]]:
    """The node commands of the README's "By hand" block (after its ``./dev shell`` line), in order."""
    text = (ROOT / "README.md").read_text()
    block = re.search(r"^### By hand\n.*?^```\n(.*?)^```", text, re.MULTILINE | re.DOTALL)
    assert block is not None, "README has a ### By hand section with a code block"
    lines = [line.split("#", 1)[0].strip() for line in block.group(1).splitlines()]
    assert lines[0].endswith("./dev shell"), lines[0]
    return [shlex.split(line) for line in lines[1:] if line]


def config_dir() -> Path:
    """``$CNC_CONFIG_DIR`` as ``./dev shell`` sets it."""
    installed = ROOT / "install" / "cnc_contour_control" / "share" / "cnc_contour_control" / "config"
    folder = Path(os.environ.get("CNC_CONFIG_DIR", installed))
    assert folder.is_dir(), f"{folder}: run ./dev setup"
    return folder


def test_the_readmes_by_hand_start_runs_the_runners_graph(tmp_path: Path) -> None:
    commands = by_hand_commands()
    assert [c[0] for c in commands] == ["recorder", "plant", "servo", "servo", "interpolator"]
    bag = tmp_path / "bag"
    processes: dict[str, subprocess.Popen[bytes]] = {}
    try:
        for i, command in reversed(list(enumerate(commands))):  # "in any order": the recorder last
            command = [f"output:={bag}" if word == f"output:={README_BAG}" else word for word in command]
            with open(tmp_path / f"{i}_{command[0]}.log", "wb") as log:
                processes[f"{i}_{command[0]}"] = subprocess.Popen(command, cwd=config_dir(), stdout=log,
                                                                  stderr=subprocess.STDOUT)
        assert processes["1_plant"].wait(timeout=180) == 0, (tmp_path / "1_plant.log").read_text()
        assert processes["0_recorder"].wait(timeout=60) == 0, (tmp_path / "0_recorder.log").read_text()
    finally:
        stop_processes(processes.values())
    recorded, verdict = judge_bag(bag)
    assert verdict.complete, verdict.describe()
    engine = run_engine(load_scenario(ROOT / "scenarios" / "paper000_circle_high.yaml"))
    assert recorded.ticks == engine.ticks > 600
    np.testing.assert_allclose(recorded.joint_states.position_m, engine.joint_states.position_m, rtol=0, atol=1e-9)
