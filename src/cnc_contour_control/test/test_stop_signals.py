"""StopSignals: a signal inside the block is noted, not acted on; the previous handlers come back after it."""
from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import threading

import pytest

from cnc_contour_control.core.stop_signals import NODE_STOP_SIGNALS, STACK_DUMP_SIGNAL, StopSignals


def test_a_signal_is_noted_the_first_counts_and_the_handler_comes_back() -> None:
    before = signal.getsignal(signal.SIGTERM)
    with StopSignals() as stop:
        assert not stop.requested and not StopSignals.stopping()
        os.kill(os.getpid(), signal.SIGTERM)  # delivered to the main thread before kill returns
        os.kill(os.getpid(), signal.SIGINT)
        assert stop.signum == signal.SIGTERM and stop.requested and StopSignals.stopping()
    assert signal.getsignal(signal.SIGTERM) is before and StopSignals.active is None


def test_the_runner_adds_sighup_and_an_inner_block_gives_the_outer_one_back() -> None:
    with StopSignals((*NODE_STOP_SIGNALS, signal.SIGHUP)) as outer:
        with StopSignals() as inner:
            assert StopSignals.active is inner
        assert StopSignals.active is outer
        os.kill(os.getpid(), signal.SIGHUP)
        assert outer.signum == signal.SIGHUP and not inner.requested
    assert StopSignals.active is None


def test_outside_the_main_thread_nothing_is_installed() -> None:
    found: list[StopSignals] = []

    def enter() -> None:
        with StopSignals() as stop:
            found.append(stop)

    worker = threading.Thread(target=enter)
    worker.start()
    worker.join()
    assert not found[0].installed and StopSignals.active is None


def test_a_process_in_the_block_prints_its_stacks_on_the_dump_signal_and_goes_on() -> None:
    """SIGUSR1 prints every thread's stack to stderr (what a node that does not stop is doing); SIGINT still stops."""
    code = ("import sys, time\n"
            "from cnc_contour_control.core.stop_signals import StopSignals\n"
            "with StopSignals() as stop:\n"
            "    print('in', flush=True)\n"
            "    while not stop.requested:\n"
            "        time.sleep(0.01)\n"
            "print('stopped', flush=True)\n")
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None and child.stdout.readline() == "in\n"
        child.send_signal(STACK_DUMP_SIGNAL)
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == 0 and out == "stopped\n", (out, err)
    assert "most recent call first" in err and 'File "<string>"' in err, err


def test_the_block_works_where_stderr_is_no_file(monkeypatch: pytest.MonkeyPatch) -> None:
    """The runner enters the block in-process, under a capture whose ``sys.stderr`` has no descriptor."""
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    with StopSignals() as stop:
        os.kill(os.getpid(), signal.SIGTERM)
    assert stop.signum == signal.SIGTERM
