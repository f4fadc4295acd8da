"""The runner's stop: SIGHUP too, and check_stop raises RunInterrupted with the shell's exit code."""
from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from cnc_tools.runs.lifetime import RunInterrupted, check_stop, runner_stop_signals


def test_sighup_stops_a_run_as_ctrl_c_does(tmp_path: Path) -> None:
    with runner_stop_signals() as signals:
        check_stop(signals, tmp_path)  # nothing came: no raise
        os.kill(os.getpid(), signal.SIGHUP)
        with pytest.raises(RunInterrupted, match=f"interrupted by SIGHUP; {tmp_path} keeps what was recorded") as err:
            check_stop(signals, tmp_path)
    assert err.value.exit_code == 128 + signal.SIGHUP and isinstance(err.value, KeyboardInterrupt)
