"""Tier 2: the bare relay graph of ``bench lockstep`` (real processes over loopback DDS) and its report rows."""
from __future__ import annotations

import os
import secrets
import signal
import threading
from pathlib import Path

import pytest

from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.testing import wait_until
from cnc_tools.bench.lockstep import EngineFigures, GraphFigures, HopFigures, collect, print_figures
from cnc_tools.bench.relay import relay_ticks

pytestmark = pytest.mark.nodes


def _pids_with(text: str) -> dict[int, str]:
    """Processes whose command line holds ``text``: pid -> command line."""
    found = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
            except OSError:
                continue
            if text in cmdline:
                found[int(entry.name)] = cmdline
    return found


def test_the_relay_graph_runs_its_ticks_and_every_process_is_reaped(tmp_path: Path) -> None:
    ns = f"/relay_test_{secrets.token_hex(4)}"
    per_tick_s = relay_ticks(tmp_path, 200, 20, namespace=ns)
    assert 0.0 < per_tick_s < 1.0
    assert not _pids_with(ns), "every relay process reaped"
    assert {p.name for p in tmp_path.glob("relay_*.log")} == {
        "relay_plant.log", "relay_interpolator.log", "relay_servo_x.log", "relay_servo_y.log"}


def test_a_relay_process_that_dies_mid_run_is_named_not_waited_for(tmp_path: Path) -> None:
    ns = f"/relay_test_{secrets.token_hex(4)}"
    failure: list[BaseException] = []

    def run() -> None:
        try:
            relay_ticks(tmp_path, 10 ** 8, 0, timeout_s=120.0, namespace=ns)
        except BaseException as err:
            failure.append(err)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    wait_until(lambda: any("--axis x" in c for c in _pids_with(ns).values()) and any(
        "plant" in c for c in _pids_with(ns).values()), 60.0, "the relay graph's servo x and plant")
    servo = next(pid for pid, cmd in _pids_with(ns).items() if "--axis x" in cmd)
    os.kill(servo, signal.SIGKILL)
    thread.join(timeout=60.0)
    assert not thread.is_alive() and failure, "relay_ticks returned or hung"
    assert isinstance(failure[0], FaultError) and "relay_servo_x" in str(failure[0]), failure[0]
    assert not _pids_with(ns), "the others stopped and reaped"


def test_the_bench_prints_what_the_nodes_add_and_what_the_topology_costs(capsys: pytest.CaptureFixture[str]) -> None:
    graph = [GraphFigures(0.001, 1000, 1.0, 1.8, 0.55, 1.8e-3, 6.0e-4, 2.4e-3, 1.3)]
    hops = [HopFigures("reference", 500, 5.0e-4, 6.0e-4, 2.5e-4), HopFigures("float64", 500, 4.0e-4, 5.0e-4, 2.0e-4)]
    engine = [EngineFigures(0.001, 6474, 3, 100.0, 110.0, 1e-5)]
    figures = collect(True, graph, hops, engine, relay_per_tick_s=1.2e-3)
    assert figures["relay"]["per_hop_s"] == pytest.approx(4.0e-4)
    assert figures["relay"]["relay_over_bare"] == pytest.approx(1.6)
    assert figures["hop_ratio"][0]["graph_over_relay"] == pytest.approx(1.5)
    assert figures["hop_ratio"][0]["ratio"] == pytest.approx(2.4) and not figures["hop_ratio"][0]["met"]
    figures["machine"]["load_average_1min_at_start"] = 1.0
    print_figures(figures)
    out = capsys.readouterr().out
    assert "bare relay graph" in out and "1.60 bare hops" in out and "graph / relay" in out
