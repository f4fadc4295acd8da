"""Fixtures of the cnc_tools tests; the synthetic data itself lives in :mod:`cnc_tools.bagio.synthetic`."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from cnc_tools.bagio.synthetic import (
    COMMAND_TYPE,
    NS,
    TOPICS,
    Trajectory,
    axis_command,
    circle_program,
    circle_trajectory,
    corner_program,
    header,
    joint_state,
    make_run,
    offset_trajectory,
    path_message,
    reference,
    write_run_bag,
)


@pytest.fixture(scope="session")
def circle_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 2-axis, 2000-sample circle run (R = 20 mm, 5 µm outside) recorded once per session."""
    program = circle_program()
    return write_run_bag(tmp_path_factory.mktemp("bags") / "circle", program, circle_trajectory(0.02, 5e-6))


@pytest.fixture(scope="session")
def synth() -> SimpleNamespace:
    """The helpers of this module, for test modules (conftest is not importable under importlib mode)."""
    return SimpleNamespace(
        circle_program=circle_program, corner_program=corner_program, circle_trajectory=circle_trajectory,
        Trajectory=Trajectory, write_run_bag=write_run_bag, path_message=path_message, joint_state=joint_state,
        reference=reference, axis_command=axis_command, header=header, TOPICS=TOPICS, NS=NS, make_run=make_run,
        offset_trajectory=offset_trajectory, COMMAND_TYPE=COMMAND_TYPE)
