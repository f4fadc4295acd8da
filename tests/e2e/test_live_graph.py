"""Tier 3: ``run --live`` through the node graph, watched by a protocol client from before the first tick.

The in-process ``live`` node reads the run's namespace and every stage waits for it, so the client gets every
tick: ``joint_states`` and the commands as the bag holds them (the same CDR bytes, on ``/cnc/...`` whatever the
run's namespace), the exact contour error as the scorer computes it from the bag, its peak exactly, and the
plant's statuses as log messages.
"""
from __future__ import annotations

from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader

from cnc_tools.analysis.scoring import contour_error_series
from cnc_tools.bagio.recording import run_namespace
from cnc_tools.bagio.typestore import project_typestore
from cnc_tools.live.watch import watch_graph_run
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
CHANNELS = ("/cnc/joint_states", "/cnc/servo/y/command", "/live/contour_error/exact",
            "/live/contour_error/exact/peaks", "/live/log", "/live/scene")
pytestmark = pytest.mark.e2e


def _bag_raw(bag: Path, relative: str) -> list[bytes]:
    with AnyReader([bag], default_typestore=project_typestore()) as reader:
        topic = f"{run_namespace(c.topic for c in reader.connections)}/{relative}"
        connections = [c for c in reader.connections if c.topic == topic]
        return [bytes(raw) for _, _, raw in reader.messages(connections=connections)]


def test_a_graph_run_watched_live_gets_every_tick_as_the_bag_holds_it(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE, {"duration_s": 1.0})  # 101 ticks at T = 10 ms
    watched = watch_graph_run(scenario, tmp_path / "run", CHANNELS)
    bag = watched.record.source
    for relative in ("joint_states", "servo/y/command"):
        live = [r.payload for r in watched.of(f"/cnc/{relative}")]
        assert len(live) == 101 and live == _bag_raw(bag, relative), relative
    series, _ = contour_error_series(watched.record)
    exact = {m["stamp_ns"]: m["contour_error_um"] for m in (r.json() for r in watched.of("/live/contour_error/exact"))}
    assert all(exact[stamp] == value for stamp, value in zip(series.stamp_ns.tolist(),
                                                             (series.error_m * 1e6).tolist()))
    peaks = [abs(r.json()["contour_error_um"]) for r in watched.of("/live/contour_error/exact/peaks")]
    assert max(peaks) == float(abs(series.error_m * 1e6).max())
    assert watched.of("/live/log") and watched.of("/live/scene")
