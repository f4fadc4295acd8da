"""Progress on stderr: a redrawn line on a real terminal (a pty), plain lines at a bounded rate into a pipe,
nothing when quiet; ``cnc-contour --version`` and ``tune``'s generations from real subprocesses."""
from __future__ import annotations

import contextlib
import fcntl
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
from collections.abc import Iterator
from importlib import metadata
from operator import methodcaller
from pathlib import Path
from typing import TextIO

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.runs.executor import LocalExecutor
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.progress import Reporter, format_duration, set_quiet
from cnc_tools.tuning.problem import Constraint, DesignVariable
from cnc_tools.tuning.solve import solve

CIRCLE = project_root() / "scenarios" / "paper000_circle_high.yaml"


class Clock:
    """A clock the test moves by hand [s]."""

    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


def _read_all(fd: int) -> str:
    """Everything written so far to the other end of ``fd``."""
    chunks = []
    while select.select([fd], [], [], 0.2)[0]:
        chunk = os.read(fd, 65536)
        if not chunk:
            break
        chunks.append(chunk)
    return b"".join(chunks).decode()


def _set_columns(fd: int, columns: int) -> None:
    fcntl.ioctl(fd, termios.TIOCSWINSZ, struct.pack("HHHH", 24, columns, 0, 0))


@pytest.fixture
def terminal() -> Iterator[tuple[TextIO, int]]:
    """A pseudo-terminal of 200 columns: the writer's end as a text stream (``isatty()`` is true), the reader's fd."""
    reader, writer = pty.openpty()
    _set_columns(writer, 200)
    stream = os.fdopen(writer, "w")
    try:
        yield stream, reader
    finally:
        stream.close()
        os.close(reader)


def _sweep(reporter: Reporter, clock: Clock, runs: int) -> None:
    """A bench of ``runs`` one-second runs, each with a two-step inner task."""
    with reporter.task("bench demo"), reporter.task("demo runs", runs) as outer:
        for _ in range(runs):
            with reporter.task("members", 2) as inner:
                inner.step()
                inner.step()
            clock.now_s += 1.0
            outer.step(note="best 1.5 um")


def test_a_terminal_gets_one_line_redrawn_in_place(terminal: tuple[TextIO, int]) -> None:
    stream, reader = terminal
    clock = Clock()
    reporter = Reporter(stream, clock=clock, redraw_s=0.0)
    assert reporter.style() == "terminal"
    _sweep(reporter, clock, runs=4)
    shown = _read_all(reader)
    assert shown.count("\n") == 1 and shown.endswith("done in 4 s\x1b[K\r\n"), repr(shown[-80:])
    draws = [d for d in shown.split("\r") if d.strip()]
    assert "bench demo › demo runs 2/4 (best 1.5 um) · 2 s elapsed · ~2 s left\x1b[K" in draws
    assert "bench demo › demo runs 1/4 (best 1.5 um) › members 2/2 · 1 s elapsed · ~3 s left\x1b[K" in draws
    assert draws[-1].startswith("bench demo · done in 4 s")


def test_output_on_the_same_terminal_clears_the_line_and_redraws_it_below(
        terminal: tuple[TextIO, int], monkeypatch: pytest.MonkeyPatch) -> None:
    stream, reader = terminal
    screen_stdout = os.fdopen(os.dup(stream.fileno()), "w")
    monkeypatch.setattr(sys, "stdout", screen_stdout)
    clock = Clock()
    reporter = Reporter(stream, clock=clock, redraw_s=0.0)
    with reporter.task("bench demo", 2) as bench:
        bench.step()
        print("table row", end="")  # a line begun: no drawing until it ends
        bench.step()
        print(" ends here")
    assert sys.stdout is screen_stdout, "the guard is taken off when the outermost task ends"
    screen_stdout.close()
    shown = _read_all(reader)
    assert shown == ("\rbench demo 0/2 · 0 s elapsed\x1b[K\rbench demo 1/2 · 0 s elapsed · ~0 s left\x1b[K"
                     "\r\x1b[Ktable row ends here\r\n\rbench demo 2/2 · 0 s elapsed · ~0 s left\x1b[K"
                     "\rbench demo 2/2 · done in 0 s\x1b[K\r\n"), repr(shown)


def test_a_narrow_terminal_gets_the_line_cut_to_its_width(terminal: tuple[TextIO, int]) -> None:
    stream, reader = terminal
    _set_columns(stream.fileno(), 40)
    clock = Clock()
    _sweep(Reporter(stream, clock=clock, redraw_s=0.0), clock, runs=2)
    draws = [d.removesuffix("\x1b[K") for d in _read_all(reader).split("\r") if d.strip()]
    assert max(len(d) for d in draws) == 39 and draws[-1] == "bench demo · done in 2 s", draws


def test_a_terminal_is_redrawn_ten_times_a_second_at_most(terminal: tuple[TextIO, int]) -> None:
    stream, reader = terminal
    clock = Clock()
    with Reporter(stream, clock=clock).task("fuzz inputs", 1000) as inputs:  # 1000 steps in 1 s
        for _ in range(1000):
            clock.now_s += 0.001
            inputs.step()
    draws = [d for d in _read_all(reader).split("\r") if d.strip()]
    assert 10 <= len(draws) <= 12, draws  # the start, one per 0.1 s, the end


def test_a_pipe_gets_plain_lines_at_tenths_and_intervals() -> None:
    reader, writer = os.pipe()
    clock = Clock()
    with os.fdopen(writer, "w") as stream:
        reporter = Reporter(stream, clock=clock, interval_s=5.0)
        assert reporter.style() == "lines"
        _sweep(reporter, clock, runs=50)  # 50 s of runs, 150 steps in all
        with reporter.task("no total") as open_ended:  # counted without a total: a line per interval at most
            for _ in range(12):
                clock.now_s += 1.0
                open_ended.step()
    with os.fdopen(reader) as written:
        lines = written.read().splitlines()
    demo = [line for line in lines if line.startswith("bench demo")]
    assert demo[0] == "bench demo · 0 s elapsed" and demo[-1] == "bench demo · done in 50 s"
    tenths = [line for line in demo if re.search(r"demo runs (5|10|15|20|25|30|35|40|45|50)/50 ", line)]
    assert len(tenths) == 10 and len(demo) == 12, demo  # start, each tenth, the end: not one per step
    assert [line.split(" · ")[0] for line in lines if line.startswith("no total")] == [
        "no total", "no total 5", "no total 10", "no total 12"]


def test_an_exception_ends_the_line_with_stopped_not_done() -> None:
    reader, writer = os.pipe()
    clock = Clock()
    with os.fdopen(writer, "w") as stream:
        reporter = Reporter(stream, clock=clock)
        with pytest.raises(KeyboardInterrupt), reporter.task("bench demo"), reporter.task("demo runs", 4) as runs:
            runs.step()
            clock.now_s += 3.0
            raise KeyboardInterrupt
        assert not reporter.tasks
    with os.fdopen(reader) as written:
        assert written.read().splitlines()[-1] == "bench demo › demo runs 1/4 · stopped after 3 s"


def test_a_closed_stream_silences_the_reporter_not_the_command() -> None:
    reader, writer = os.pipe()
    os.close(reader)  # the reading end is gone: a write raises BrokenPipeError
    with os.fdopen(writer, "w") as stream:
        clock = Clock()
        reporter = Reporter(stream, clock=clock)
        _sweep(reporter, clock, runs=3)
        assert reporter.tasks == []
        with contextlib.suppress(BrokenPipeError):  # what the failed write left in the buffer
            stream.close()


def test_quiet_writes_nothing() -> None:
    reader, writer = os.pipe()
    clock = Clock()
    with os.fdopen(writer, "w") as stream:
        reporter = Reporter(stream, mode="quiet", clock=clock)
        _sweep(reporter, clock, runs=3)
    with os.fdopen(reader) as written:
        assert written.read() == ""


def test_a_pool_worker_is_quiet() -> None:
    """Progress is the parent's: a spawned worker's reporter writes nothing, even with lines asked for."""
    with LocalExecutor(2, progress=False) as pool:
        styles = pool.map(methodcaller("style"), [Reporter(mode="lines"), Reporter(mode="terminal")])
    assert styles == ["quiet", "quiet"] and Reporter(mode="lines").style() == "lines"


def test_bad_options_are_refused_naming_them() -> None:
    with pytest.raises(ConfigError, match="interval_s must be > 0, got 0"):
        Reporter(interval_s=0)
    with pytest.raises(ConfigError, match="redraw_s must be >= 0, got -1"):
        Reporter(redraw_s=-1)
    with pytest.raises(ConfigError, match="total must be None or an integer >= 0, got -1"):
        Reporter(mode="quiet").task("runs", -1)
    assert [format_duration(s) for s in (4.6, 125, 7620)] == ["5 s", "2 min 05 s", "2 h 07 min"]


def _first(x: np.ndarray) -> float:
    return float(x[0])


def _first_figure(x: np.ndarray) -> list[float]:
    return [float(x[0])]


@pytest.mark.parametrize(("bound", "note"), [
    (0.5, r"best [0-9.e+-]+ um, meets the constraints"),
    (5.0, r"no member meets the constraints, least violation 4"),
])
def test_each_tune_generation_says_whether_its_best_meets_the_constraints(
        bound: float, note: str, capsys: pytest.CaptureFixture[str]) -> None:
    set_quiet(False)
    solve(_first, (DesignVariable("a", 0.0, 1.0),), (Constraint("a", ">=", bound),), _first_figure,
          maxiter=3, popsize=3, unit="um")
    lines = capsys.readouterr().err.splitlines()  # not a terminal under capsys: plain lines
    assert re.match(rf"tune generation 3/3 \({note}[0-9.]*\) · done in ", lines[-1]), lines


def _cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "cnc_tools.cli.main", *args], capture_output=True, text=True,
                          timeout=300, cwd=cwd)


def test_version_names_the_installed_package_and_the_commit() -> None:
    shown = _cli("--version")
    assert shown.returncode == 0, shown.stderr
    found = re.fullmatch(r"cnc-contour (\S+)(?: \(git ([0-9a-f]{7,40})\))?\n", shown.stdout)
    assert found and found[1] == metadata.version("cnc_tools"), shown.stdout
    if (project_root() / ".git").exists():
        head = subprocess.run(["git", "-C", str(project_root()), "rev-parse", "HEAD"], capture_output=True,
                              text=True, check=True).stdout
        assert found[2] and head.startswith(found[2])


def test_tune_shows_each_generation_on_stderr_and_leaves_stdout_alone(tmp_path: Path) -> None:
    """The analytic objective (paper 003's model): a search of 4 generations in about a second."""
    problem = ["tune", str(CIRCLE), "--var", "plant.axis_overrides.*.ki=10:100", "--var",
               "plant.axis_overrides.*.kp=0.1:2.6", "--constraint", "phase_margin_eq15_deg>=60", "--maxiter", "4",
               "--popsize", "3", "--out", str(tmp_path)]
    shown, quiet = _cli(*problem), _cli(*problem, "--quiet")
    assert shown.returncode == quiet.returncode == 0, shown.stderr + quiet.stderr
    assert shown.stdout == quiet.stdout and "objective" in shown.stdout
    assert quiet.stderr == ""
    generations = re.findall(r"^tune generation (\d)/4 \(best [0-9.e+-]+ um, meets the constraints\)", shown.stderr,
                             re.M)
    assert generations[:4] == ["1", "2", "3", "4"], shown.stderr
    assert shown.stderr.splitlines()[-1].startswith("tune generation 4/4 (best ")
    assert " · done in " in shown.stderr.splitlines()[-1]
