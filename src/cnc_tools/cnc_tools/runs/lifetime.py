"""How a run's processes end with their runner: stop signals, death of the parent, the last word in summary.json.

Every way out of ``cnc-contour run`` stops and reaps the graph:

* SIGINT, SIGTERM, SIGHUP to the runner: :class:`~cnc_contour_control.core.stop_signals.StopSignals`
  notes the first signal (later ones are ignored while the stop is under way) and
  the runner's wait loop raises :class:`RunInterrupted` at its next poll
  (:func:`check_stop`, within 50 ms), so
  :class:`~cnc_tools.runs.graph.GraphRun` stops every node (SIGINT, SIGTERM,
  SIGKILL) and reaps it; the recorder closes its bag.
* An exception in the runner: the same stop, from ``GraphRun.__exit__``.
* The runner killed (SIGKILL, a crash of the interpreter): every node is
  started with :func:`die_with_parent` as its ``preexec_fn``, which asks Linux
  (``prctl(PR_SET_PDEATHSIG, SIGTERM)``) to send it SIGTERM when the runner dies;
  the nodes then stop as on a SIGTERM (the recorder closes its bag, the plant
  writes an ``interrupted`` summary).

:func:`settle_summary` gives ``summary.json`` its last word when the plant could
not (killed, never started): ``summary.json`` never says ``running`` after a run.
"""
from __future__ import annotations

import ctypes
import json
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from cnc_contour_control.core.stop_signals import StopSignals

#: Signals that stop a run cleanly (the runner's own SIGINT handler replaces KeyboardInterrupt).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
#: Signal a node gets when its runner dies (Linux only).
PARENT_DEATH_SIGNAL = signal.SIGTERM
_PR_SET_PDEATHSIG = 1


class RunInterrupted(KeyboardInterrupt):
    """The runner got a stop signal; the run was stopped and its processes reaped.

    A :class:`KeyboardInterrupt`, so callers treat SIGTERM and SIGHUP as they treat Ctrl-C.
    ``exit_code`` is the shell's convention, 128 + the signal number.
    """

    def __init__(self, signum: int, run_dir: Path | None = None) -> None:
        self.signum = signum
        self.exit_code = 128 + signum
        where = f"; {run_dir} keeps what was recorded" if run_dir is not None else ""
        super().__init__(f"interrupted by {signal.Signals(signum).name}{where}")


def runner_stop_signals() -> StopSignals:
    """The runner's stop signals (:data:`STOP_SIGNALS`), for a ``with`` around its wait loop."""
    return StopSignals(STOP_SIGNALS)


def check_stop(signals: StopSignals, run_dir: Path | None = None) -> None:
    """Raise :class:`RunInterrupted` if a stop signal reached ``signals`` (``run_dir`` keeps what was recorded)."""
    if signals.signum is not None:
        raise RunInterrupted(signals.signum, run_dir)


def die_with_parent() -> Callable[[], None] | None:
    """A ``preexec_fn`` that makes the child get SIGTERM when this process dies (None where Linux's prctl is missing).

    The death signal follows the *thread* that started the child: start a run's
    nodes from a thread that lives as long as the run (the runner's wait does).
    If the parent died between fork and prctl, the child ends itself at once.
    """
    if not sys.platform.startswith("linux"):
        return None
    prctl = ctypes.CDLL(None, use_errno=True).prctl  # resolved here: the child only calls it
    parent = os.getpid()

    def preexec() -> None:
        prctl(_PR_SET_PDEATHSIG, int(PARENT_DEATH_SIGNAL), 0, 0, 0)
        if os.getppid() != parent:
            os.kill(os.getpid(), PARENT_DEATH_SIGNAL)

    return preexec


def read_summary(path: Path) -> dict[str, Any] | None:
    """The summary in ``path``; None when absent or unreadable (a plant killed while writing it)."""
    try:
        summary = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return summary if isinstance(summary, dict) else None


def amend_summary(path: Path, values: Mapping[str, Any]) -> dict[str, Any]:
    """Add the runner's ``values`` (what only the scenario knows, e.g. ``ends_by``) to the plant's ``summary.json``
    of a run that ended, and return it."""
    summary = {**(read_summary(path) or {}), **values}
    _write_summary(path, summary)
    return summary


def _write_summary(path: Path, summary: Mapping[str, Any]) -> None:
    """Write ``summary.json`` atomically (a reader sees the old or the new file, never half of one)."""
    partial = path.with_name(f".{path.name}.partial")
    partial.write_text(json.dumps(summary, indent=2))
    os.replace(partial, path)


def settle_summary(path: Path, status: str, reason: str, exit_codes: Mapping[str, int | None]) -> dict[str, Any]:
    """Give ``summary.json`` the runner's account of a run that did not end well, and return it.

    The plant's own ``finished`` or ``faulted`` stays; anything else (``running``,
    the plant's ``interrupted``, no summary at all) becomes ``status`` with
    ``reason``. A node that died is a fault of the run. The exit codes of every
    node are kept under ``exit_codes``.
    """
    summary = read_summary(path) or {"ticks": 0, "simulated_time_s": 0.0, "wall_time_s": 0.0,
                                     "real_time_factor": float("nan"), "faults": []}
    if summary.get("status") in ("finished", "faulted"):
        summary.setdefault("runner_problems", []).append(reason)
    else:
        summary.update(status=status, reason=reason)
        if status == "node died":
            summary["faults"] = [*summary.get("faults", []), reason]
    summary["exit_codes"] = dict(exit_codes)
    _write_summary(path, summary)
    return summary


def stop_process(process: subprocess.Popen[Any], timeout_s: float) -> None:
    """SIGINT ``process`` (a runner stops its nodes on it), SIGKILL it if it has not ended within ``timeout_s``;
    reap it."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            process.kill()
    process.wait()
