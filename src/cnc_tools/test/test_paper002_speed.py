"""Bench ``paper002-speed``: every law timed beside P in one run; the PDC's design time per spare-DOF reading."""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from cnc_tools.bench.registry import BENCHES
from cnc_tools.reproductions.paper002.speed import SPARE_DOFS, TIMED, design_times_s, step_costs_us


def test_every_law_is_timed_at_both_levels() -> None:
    costs = step_costs_us(2000, repeats=2)
    assert set(costs) == {"law step", "servo step"}
    for level in costs.values():
        # what each costs, and which costs more, is the bench's to compare side by side with the load beside it;
        # here only that every law was timed (a loaded machine can make any one step slow)
        assert set(level) == set(TIMED) and all(math.isfinite(us) and us > 0.0 for us in level.values())


def test_each_spindle_change_is_a_fresh_design() -> None:
    times = design_times_s(2)
    assert set(times) == set(SPARE_DOFS) and all(len(found) == 2 for found in times.values())
    # timings are the bench's to compare (side by side, with the load); here only that each design was made
    assert all(0.0 < t < 60.0 for found in times.values() for t in found)


def test_the_bench_writes_its_figures(tmp_path: Path, monkeypatch) -> None:
    import cnc_tools.reproductions.paper002.speed as speed

    monkeypatch.setattr(speed, "REPEATS", 2)
    out = tmp_path / "speed.json"
    assert BENCHES["paper002-speed"](argparse.Namespace(name="paper002-speed", quick=True, json=out)) == 0
    found = json.loads(out.read_text())
    assert set(found["step_us"]["law step"]) == set(TIMED) and set(found["design_s"]) == set(SPARE_DOFS)
