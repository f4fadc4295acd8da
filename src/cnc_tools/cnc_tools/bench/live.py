"""``cnc-contour bench live``: the lag from a tick to a viewer at T = 1 ms, the CPU per tick, and the peak check.

paper 000's circle at T = 1 ms on the engine with ``--live`` (paced in real time). The viewer is the protocol
client (:class:`cnc_tools.live.client.LiveClient`) in a process of its own, as Foxglove is: it subscribes
before the first tick, first to the channels the shipped layout shows, then to every channel (each full-rate
stream at once, every CDR message made). The lag of a message is its arrival at the viewer minus its log time
(the wall time its tick reached the feed); the goal is a largest lag <= 100 ms over every channel of both runs.
The feed's share is printed apart: per batch, the wall time from its first tick to its last message handed to the
server (the rest is the socket and the viewer's process, scheduled among the machine's load).
CPU per tick is this process's CPU time (the engine's thread, the sender thread, the server's threads; not the
viewer's) over the run's ticks: the engine alone and with --live, both unpaced (the live code's own cost) and both
paced in real time (the sleeps and cold wake-ups add theirs), and with each viewer. The exact
contour error's peak stream must hold the run's peak as the scorer computes it, exactly. The 1-minute load is
printed before and after (the lag is the machine's as much as the code's).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.core.errors import CncError
from cnc_tools.analysis.scoring import contour_error_series
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.live.engine import AHEAD_NS, MAX_RATE
from cnc_tools.live.layout import LAYOUT_PATH, layout_topics
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import Scenario, load_scenario

SCENARIO = "scenarios/paper000_circle_high.yaml"
SAMPLE_TIME_S = 0.001
#: The goal: a tick reaches a viewer within this, ms.
LAG_GOAL_MS = 100.0
#: Channels whose lag is reported (the per-tick CDR ones, the full-rate exact error, the peak streams, xy).
REPORTED = ("/cnc/joint_states", "/cnc/servo/x/command", "/live/contour_error/exact",
            "/live/contour_error/exact/peaks", "/live/servo/x/peaks", "/live/xy")
PEAKS = "/live/contour_error/exact/peaks"
#: Per run (the viewer's subscription), each batch's wall time from its first tick to its last message in the server.
HANDOFF_MS: dict[tuple[str, ...] | None, list[float]] = {}
#: Seconds the viewer waits for the server to close.
VIEWER_TIMEOUT_S = 300.0


def viewer(url: str, out: Path, topics: list[str]) -> None:
    """The viewer process: subscribe to ``topics`` (every channel when empty), say so on stdout, collect until the
    server closes, write (topic, log time, arrival, peak payload) rows to ``out`` as JSON."""
    from cnc_tools.live.client import LiveClient

    with LiveClient(url) as client:
        client.wait_channels(("/cnc/joint_states",))
        client.subscribe([t for t in topics if t in client.channels] if topics else sorted(client.channels))
        print("subscribed", flush=True)
        client.collect(lambda _: False, VIEWER_TIMEOUT_S)
    out.write_text(json.dumps([(r.topic, r.log_time_ns, r.arrived_ns, r.payload.decode() if r.topic == PEAKS else "")
                               for r in client.pending]), encoding="utf-8")


def _cpu_run(scenario: Scenario, subscribed: tuple[str, ...] | None,
             rate: float = 1.0) -> tuple[float, list[Any], Any]:
    """One live run paced at ``rate`` (no viewer when ``subscribed`` is None): (CPU per tick [µs], the viewer's rows,
    the run's record)."""
    from cnc_tools.live.options import engine_live
    from cnc_tools.live.watch import live_args
    from cnc_tools.runs.engine import run_engine

    with tempfile.TemporaryDirectory() as folder:
        out, process = Path(folder) / "viewer.json", None
        with engine_live(live_args(rate), scenario) as live:
            observer: Any = live["on_tick"]  # an EngineLive
            if subscribed is not None:
                process = subprocess.Popen([sys.executable, "-m", "cnc_tools.bench.live", observer.feed.server.url,
                                            str(out), *subscribed], stdout=subprocess.PIPE, text=True)
                assert process.stdout is not None  # piped
                if process.stdout.readline().strip() != "subscribed":
                    process.kill()
                    raise CncError(f"the viewer process did not subscribe (exit {process.wait()})")
            started = time.process_time()
            record = run_engine(scenario, on_tick=observer)
            observer.close()  # the sender's last batch, counted
            cpu_us = (time.process_time() - started) / record.summary["ticks"] * 1e6
            HANDOFF_MS[subscribed] = [ns * 1e-6 for ns in observer.handoff_ns]
        if process is None:
            return cpu_us, [], record
        if process.wait(VIEWER_TIMEOUT_S) != 0:
            raise CncError(f"the viewer process failed (exit {process.returncode})")
        return cpu_us, json.loads(out.read_text(encoding="utf-8")), record


class _Paced:
    """The engine paced as ``EngineLive`` paces it (a burst of ticks up to ``AHEAD_NS`` ahead, then a sleep), nothing
    streamed: the CPU the pacing costs by itself (a thread woken ~100 times a second on a loaded machine runs cold)."""

    def __init__(self) -> None:
        self.start_ns: int | None = None

    def __call__(self, board: Any, stages: Any) -> None:
        now = time.monotonic_ns()
        if self.start_ns is None:
            self.start_ns = now - board.stamp_ns
        if self.start_ns + board.stamp_ns - now > AHEAD_NS:
            time.sleep((self.start_ns + board.stamp_ns - now) * 1e-9)


def _engine_cpu_us(scenario: Scenario, on_tick: Any = None) -> float:
    """CPU per tick of the engine alone [µs], unpaced (or paced by ``on_tick``)."""
    from cnc_tools.runs.engine import run_engine

    started = time.process_time()
    ticks = run_engine(scenario, on_tick=on_tick).summary["ticks"]
    return (time.process_time() - started) / ticks * 1e6


def _lag_rows(label: str, received: list[Any]) -> tuple[list[tuple[Any, ...]], float]:
    """The lag rows of the reported channels, and the largest lag of any channel [ms]."""
    lags: dict[str, list[float]] = {}
    for topic, log_ns, arrived_ns, _ in received:
        lags.setdefault(topic, []).append((arrived_ns - log_ns) * 1e-6)
    rows = [(label, topic, len(lags[topic]), round(float(np.median(lags[topic])), 2),
             round(float(np.percentile(lags[topic], 99)), 2), round(max(lags[topic]), 2))
            for topic in REPORTED if topic in lags]
    return rows, max((max(v) for v in lags.values()), default=float("nan"))


def live_bench(args: argparse.Namespace) -> int:
    """CPU per tick (engine alone, --live unwatched, each viewer), the lag table, the peak check and the load;
    0 when the lag goal is met on every channel and the peak is kept."""
    overrides: dict[str, Any] = {"sample_time_s": SAMPLE_TIME_S}
    if args.quick:
        overrides["duration_s"] = 2.0
    scenario = load_scenario(project_root() / SCENARIO, overrides)
    layout = tuple(sorted(layout_topics(json.loads(LAYOUT_PATH.read_text(encoding="utf-8")))))
    load_before = os.getloadavg()[0]
    print(f"bench live: {scenario.name} at T = {SAMPLE_TIME_S * 1e3:g} ms, {scenario.duration_s:.2f} s in real "
          f"time, unwatched, then a viewer process on the layout's channels, then on every channel "
          f"(load {load_before:.2f})", flush=True)
    unpaced = min(_engine_cpu_us(scenario) for _ in range(2))  # the first also loads and warms up
    paced = _engine_cpu_us(scenario, _Paced())
    cpu = {"engine alone, unpaced": unpaced, "--live, unpaced (rate 1000), no viewer": _cpu_run(
        scenario, None, MAX_RATE)[0], "engine alone, paced as --live": paced}
    cpu["--live, no viewer"], _, _ = _cpu_run(scenario, None)
    cpu["--live, viewer on the layout's channels"], on_layout, record = _cpu_run(scenario, layout)
    cpu["--live, viewer on every channel"], on_every, _ = _cpu_run(scenario, ())
    load_after = os.getloadavg()[0]
    rows, worst_layout_ms = _lag_rows("layout", on_layout)
    every, worst_every_ms = _lag_rows("every channel", on_every)
    print(format_table(("run", "CPU per tick [us]", "x engine alone at that pace"),
                       [(k, round(v, 1), round(v / (unpaced if "unpaced" in k else paced), 2))
                        for k, v in cpu.items()]))
    print(format_table(("subscribed", "channel", "messages", "lag median [ms]", "p99 [ms]", "max [ms]"),
                       rows + every))
    handoff = [(label, round(float(np.median(HANDOFF_MS[key])), 2), round(float(np.percentile(HANDOFF_MS[key], 99)), 2),
                round(max(HANDOFF_MS[key]), 2)) for label, key in (("layout", layout), ("every channel", ()))]
    print(format_table(("subscribed", "tick to server: median [ms]", "p99 [ms]", "max [ms]"), handoff))
    series, _ = contour_error_series(record)
    streamed = max(abs(json.loads(payload)["contour_error_um"]) for topic, *_, payload in on_layout if topic == PEAKS)
    scored = float(np.abs(series.error_m * 1e6).max())
    kept = streamed == scored
    worst_ms = max(worst_layout_ms, worst_every_ms)
    met = worst_ms <= LAG_GOAL_MS
    print(f"  lag max {worst_layout_ms:.1f} ms on the layout's channels, {worst_every_ms:.1f} ms on every channel "
          f"(goal <= {LAG_GOAL_MS:g} ms on every channel: {'met' if met else 'NOT met'})"
          f"\n  contour-error peak: peak stream {streamed:.6f} um, scorer {scored:.6f} um: "
          f"{'kept exactly' if kept else 'NOT kept'}\n  load (1 min) {load_before:.2f} before, {load_after:.2f} "
          f"after; {os.cpu_count()} cores")
    write_json(args.json, {"cpu_us_per_tick": cpu,
                           "lag_ms": {f"{r[0]} {r[1]}": {"median": r[3], "p99": r[4], "max": r[5]}
                                      for r in rows + every},
                           "lag_max_ms": {"layout": worst_layout_ms, "every channel": worst_every_ms},
                           "tick_to_server_ms": {r[0]: {"median": r[1], "p99": r[2], "max": r[3]} for r in handoff},
                           "peak_um": {"streamed": streamed, "scored": scored, "kept": kept},
                           "load": [load_before, load_after], "machine": machine()})
    return 0 if kept and met else 1


if __name__ == "__main__":  # the viewer process: URL OUT [TOPIC ...]
    viewer(sys.argv[1], Path(sys.argv[2]), sys.argv[3:])
