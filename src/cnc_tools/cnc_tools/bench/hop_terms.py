"""What the hop benches (``lockstep``, ``hops``) share: the scenario, the hops per tick, the goal."""
from __future__ import annotations

from typing import Any

from cnc_tools.runs.folders import project_root
from cnc_tools.runs.scenario import Scenario, load_scenario

SCENARIO = "scenarios/paper000_circle_high.yaml"
#: Hops on a tick's critical path: plant -> interpolator -> servo -> plant (the servos run in parallel).
HOPS = 3
#: Goal: a graph hop costs at most this many bare rclpy hops (issue 9; issue 7 asked for 2).
HOP_RATIO_GOAL = 1.5


def scenario_at(sample_time_s: float, duration_s: float | None) -> Scenario:
    """The benches' scenario at ``sample_time_s`` (and a shorter duration, if given)."""
    overrides: dict[str, Any] = {"sample_time_s": sample_time_s}
    if duration_s is not None:
        overrides["duration_s"] = duration_s
    return load_scenario(project_root() / SCENARIO, overrides)
