"""Bench ``blending``, dense CAM: a program of many short segments streamed tick by tick as the node streams it.

The program (:func:`dense_spiral`) is an Archimedean spiral from R 10 mm, 1 mm a turn, in chords of
``F T`` (1300 mm/min, T = 1 ms: one programmed segment per tick), ``--segments`` of them (150 000 by
default: 150 s at the programmed feed; 10 000 with ``--quick``). Its curvature asks at most 47 mm/s² at
that feed, so the limits allow the programmed feed everywhere but the start and the end.

It runs through :class:`~cnc_contour_control.motion.feed_override.LiveReference` (what the interpolator
node calls each tick; override 100 %) with a window of ``WINDOW`` planned segments, so the plan streams
(:mod:`cnc_contour_control.motion.plan_stream`): each tick plans at most one small step ahead and forgets
what is behind the tool. Printed: the CPU time of the ticks (median, p99.9, max; a tick over
``TICK_BUDGET_S`` counts as late: the other stages of a composed 1 kHz loop take about 0.37 ms,
``bench compose``), the feed over the programmed feed from 2 mm after the start to 2 mm before the end
(goal >= 0.9), and the plan's held entries (:meth:`StreamPlan.held_rows`) at the start, the largest in each
half of the run and at the end (goal: the second half's largest no larger than the first's).

The same stream again with the jerk bench's limit (:data:`~cnc_tools.bench.blending_limits.MAX_JERK_M_S3`) under
the default ``jerk_mode`` fir, which then streams too (:mod:`cnc_contour_control.motion.jerk_stream`): the same
figures, the worst velocity, acceleration and jerk ratio of the ticks' filtered reference
(:func:`~cnc_tools.bench.blending_limits.sampled_ratios`, every tick) and its largest distance from the programmed
spiral over P: the planner's own check (every tick's filtered point against the segments its samples come from)
and, independent of it, the exact distance to the whole spiral of every ``DEVIATION_STRIDE``-th tick (every tick
costs about 25 minutes at 150 000 segments, every 10th 2.5); and the chunks the planner planned again or left over P.

Then the same program as G-code (``G64 P0.01``, a 10 mm lead-in from the origin) through the node graph in
real time at T = 1 ms, the loop composed in one process (``--compose loop``, paper 000's drives and PID, the
override at 100 % from a schedule so the node steps a ``LiveReference``): the plant's late commands over
ticks times axes, its mean tick period (a real-time plant's timer stretches under load: each tick steps the
wall time elapsed) and whether the run ended whole; beside the same run planned whole before it starts (the
default window), which has no planning on line: what load alone does. The plant's period fault
(``max_period_ratio``) is off in these runs (scenario ``realtime`` section), so a run the machine cannot hold at
1 kHz still ends whole and its mean period is measured, not cut short. The runs are recorded: the
interpolator's ``streaming plan`` statuses give the ticks that waited for the planner (the late ticks planning
caused) and the rows the plan held each second (first, largest, last).
"""
from __future__ import annotations

import argparse
import math
import os
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.core.config import read_yaml_mapping
from cnc_contour_control.core.errors import CncError, ConfigError
from cnc_contour_control.motion.feed_override import LiveReference, OverrideConfig
from cnc_contour_control.motion.geometry import Program
from cnc_tools.analysis.tables import format_table, goal_text
from cnc_tools.bench.blending_corpus import FEED_M_S, polyline
from cnc_tools.bench.blending_limits import MAX_JERK_M_S3, bench_config, limits_for, sampled_ratios
from cnc_tools.runs.folders import project_root, timestamp

SEGMENTS = 150_000
QUICK_SEGMENTS = 10_000
TICK_S = 1e-3
#: The planned segments the stream looks ahead (braking from the feed takes about 45 of these chords).
WINDOW = 200
#: A tick whose reference took more CPU than this is late (1 ms less the composed loop's other stages).
TICK_BUDGET_S = 0.5e-3
FEED_GOAL = 0.9
#: A real-time graph run holds 1 kHz when its mean tick period is within this multiple of T (and no command is late).
PERIOD_HELD = 1.05
#: Every how many ticks the jerk run's reference is measured against the whole spiral.
DEVIATION_STRIDE = 50
#: Distance from the start and from the end left out of the feed ratio (the ramps), m.
RAMP_M = 0.002


def add_options(parser: argparse.ArgumentParser) -> None:
    """``--segments`` (bench blending)."""
    parser.add_argument("--segments", type=int, help=f"bench blending: segments of the dense-CAM program "
                        f"(default {SEGMENTS}, {QUICK_SEGMENTS} with --quick)")


def dense_spiral(segments: int, chord_m: float = FEED_M_S * TICK_S, start_radius_m: float = 0.01,
                 pitch_m: float = 0.001) -> Program:
    """An Archimedean spiral in ``segments`` chords of about ``chord_m`` from ``start_radius_m`` outward."""
    theta = np.zeros(segments + 1)
    for k in range(segments):  # the chord of a step dθ at radius r is about r dθ
        theta[k + 1] = theta[k] + chord_m / (start_radius_m + pitch_m * theta[k] / (2.0 * math.pi))
    radius = start_radius_m + pitch_m * theta / (2.0 * math.pi)
    program = polyline("dense-spiral", np.c_[radius * np.cos(theta), radius * np.sin(theta)])
    return Program(f"dense-spiral-{segments}", program.axis_names, program.segments)


def stream_run(program: Program, jerk: bool = False) -> dict[str, Any]:
    """Step ``program`` at 1 ms ticks of the wall clock with a streaming window; per-tick latency, feed, memory
    (with ``jerk``: the jerk bench's limit, fir, and the reference's limit ratios and deviation)."""
    config = OverrideConfig(schedule_times_s=(0.0,), schedule_ratios=(1.0,))
    started = time.process_time()
    limits = limits_for(program, jerk)
    live = LiveReference(program, limits, replace(bench_config(), look_ahead_segments=WINDOW), config)
    if live.planner is None:
        raise ConfigError(f"{program.name}: {len(program.segments)} segments do not stream with a window of {WINDOW}")
    construct_s = time.process_time() - started
    stream = live.planner.stream
    tick_s, feed, path, held, rows = [], [], [], [stream.held_rows()], []
    clock, tick, next_s = time.perf_counter, 0, time.perf_counter()
    while True:
        next_s += TICK_S
        before = clock()
        sample = live.step(round(tick * TICK_S * 1e9), 1.0)
        tick_s.append(clock() - before)
        feed.append(sample.feed_m_s / sample.programmed_feed_m_s)
        path.append(sample.path_length_m)
        rows.append(np.concatenate([sample.position_m, sample.velocity_m_s, sample.acceleration_m_s2]))
        if tick % 1000 == 0:
            held.append(stream.held_rows())
        if sample.done:
            break
        tick += 1
        time.sleep(max(next_s - clock(), 0.0))
    held.append(stream.held_rows())
    figures = _figures(program, construct_s, np.array(tick_s), np.array(feed), np.array(path), held,
                       stream.total_length_m)
    out = {**figures, "planner_waits": live.planner.waits, "load_1min": os.getloadavg()[0],
           "jerk_mode": live.interpolator.jerk_mode_used}
    if jerk:
        out.update(_reference_figures(program, np.array(rows), live))
    return out


def _reference_figures(program: Program, rows: np.ndarray, live: LiveReference) -> dict[str, Any]:
    """The ticks' reference (rows: position, velocity, acceleration) against the limits and P."""
    n = program.n_axes
    ratios = sampled_ratios(rows[:, :n], rows[:, n:2 * n], rows[:, 2 * n:], TICK_S, n)
    tolerance_m = live.interpolator.config.path_tolerance_mm * 1e-3
    stream = live.planner.stream if live.planner is not None else None
    assert stream is not None  # stream_run refuses a program that does not stream
    return {"velocity_ratio": float(ratios["velocity_ratio"].max()),
            "acceleration_ratio": float(ratios["acceleration_ratio"].max()),
            "jerk_ratio": float(ratios["jerk_ratio"].max()),
            "deviation_over_p": float(program.contour_distance(rows[::DEVIATION_STRIDE, :n])[0].max()) / tolerance_m,
            "checked_deviation_over_p": stream.worst_deviation_m / tolerance_m,
            "replanned_chunks": stream.replanned_chunks, "over_tolerance_chunks": stream.over_tolerance_chunks}


def _figures(program: Program, construct_s: float, tick_s: np.ndarray, feed: np.ndarray, path_m: np.ndarray,
             held: list[int], total_m: float) -> dict[str, Any]:
    middle = (path_m > RAMP_M) & (path_m < total_m - RAMP_M)
    half = len(held) // 2
    return {"program": program.name, "segments": len(program.segments), "window": WINDOW, "ticks": len(tick_s),
            "plan_cpu_s": construct_s, "tick_p50_s": float(np.median(tick_s)),
            "tick_p999_s": float(np.quantile(tick_s, 0.999)), "tick_max_s": float(tick_s.max()),
            "late_ticks": int(np.count_nonzero(tick_s > TICK_BUDGET_S)),
            "feed_ratio_min": float(feed[middle].min()),
            "feed_ratio_share_ok": float(np.mean(feed[middle] >= FEED_GOAL)),
            "held_start": held[0], "held_max_first_half": max(held[:half + 1]),
            "held_max_second_half": max(held[half:]), "held_end": held[-1]}


def gcode(program: Program) -> str:
    """``program``'s lines as G-code in mm (``G64 P0.01``, at ``FEED_M_S``), from the origin to its first point."""
    points = [program.segments[0].start_m] + [segment.end_m for segment in program.segments]
    lines = ["%", "G21 G90 G17 G64 P0.01", f"G1 F{FEED_M_S * 60000:.0f}"]
    lines += [f"X{x * 1e3:.5f} Y{y * 1e3:.5f}" for x, y in points]
    return "\n".join(lines + ["M30", "%", ""])


def graph_run(program: Program, run_dir: Path, window: int = WINDOW, jerk: bool = False,
              planner: str = "process") -> dict[str, Any]:
    """``program`` through the composed node graph in real time at T = 1 ms with a look-ahead of ``window``
    planned segments (with ``jerk``, the jerk bench's limit on every axis: the default ``fir`` streams), streamed
    by ``planner`` (the interpolator's ``stream_planner``); the plant's late commands and mean tick period."""
    from cnc_tools.runs.graph import run_graph  # the node graph's runner: only this part of the bench needs it
    from cnc_tools.runs.scenario import build_scenario

    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "dense.ngc").write_text(gcode(program))
    raw = read_yaml_mapping(project_root() / "scenarios" / "paper000_circle_high.yaml", "scenario file")
    raw.update({"name": "dense_cam", "sample_time_s": TICK_S, "mode": "realtime", "paper": None,
                "program": {"axes": ["x", "y"], "gcode_file": "dense.ngc"},
                "interpolator": {"look_ahead_segments": window, "stream_planner": planner},
                "feed_override": {"max_ratio": 1.0, "schedule": [[0.0, 1.0]]}})
    if jerk:
        raw["limits"] = {**raw["limits"], "max_jerk_mm_s3": MAX_JERK_M_S3 * 1e3}
    raw["realtime"] = {"max_period_ratio": 0.0}  # measured here, not faulted on (see the module docstring)
    scenario = build_scenario({k: v for k, v in raw.items() if v is not None}, base_dir=run_dir)
    try:
        result = run_graph(scenario, run_dir, record=True, compose="loop", timeout_s=3600.0)
    except CncError as err:  # a run that faults is a row that says so, not the bench's end
        return {"graph_window": window, "graph_jerk": jerk, "graph_planner": planner, "graph_status": "fault",
                "graph_ticks": 0, "graph_simulated_s": 0.0, "graph_mean_period_s": math.nan,
                "graph_late_commands": 0, "graph_late_share": math.nan, "graph_faults": [str(err)],
                "graph_load_1min": os.getloadavg()[0], "graph_planner_waits": None, "graph_held_rows": None,
                "graph_child_held_rows": None}
    ticks = int(result.summary.get("ticks", 0))
    late = int(result.summary.get("late_commands", 0))
    simulated_s = float(result.summary.get("simulated_time_s", 0.0))
    return {"graph_window": window, "graph_jerk": jerk, "graph_planner": planner,
            "graph_status": result.summary.get("status"), "graph_ticks": ticks,
            "graph_simulated_s": simulated_s,
            "graph_mean_period_s": simulated_s / max(ticks, 1), "graph_late_commands": late,
            "graph_late_share": late / max(ticks * 2, 1), "graph_faults": result.faults,
            "graph_load_1min": os.getloadavg()[0], **_plan_figures(result.bag_path)}


def _plan_figures(bag: Path | None) -> dict[str, Any]:
    """The interpolator's last ``streaming plan`` status in ``bag``: ticks that waited for the planner, and the rows
    held (first, largest, last of the statuses); None each for a plan made whole (no such status)."""
    from cnc_contour_control.nodes.interpolator_node import PLAN_STATUS  # the graph part only: rclpy
    from cnc_tools.bagio.diagnostics import read_statuses

    statuses = [] if bag is None else [s.values for s in read_statuses(bag)[1] if s.message == PLAN_STATUS]
    held = [int(v["plan_held_rows"]) for v in statuses]
    child = [int(v["plan_process_held_rows"]) for v in statuses if int(v.get("plan_process_held_rows", "0"))]
    return {"graph_planner_waits": int(statuses[-1]["planner_waits"]) if statuses else None,
            "graph_held_rows": (held[0], max(held), held[-1]) if held else None,
            "graph_child_held_rows": (child[0], max(child), child[-1]) if child else None}


def _graph_label(run: dict[str, Any]) -> str:
    """A graph run's row label: streamed (with the jerk limit: fir) or planned whole."""
    if run["graph_window"] != WINDOW:
        return "planned whole before the run"
    return (f"streamed, window {WINDOW}" + (", jerk limit (fir)" if run["graph_jerk"] else "")
            + f", planned in a {run['graph_planner']}")


def dense_cam(options: argparse.Namespace) -> dict[str, Any]:
    """Print and return the dense-CAM stream's figures: in process (without and with the jerk limit), then through
    the composed graph."""
    segments = getattr(options, "segments", None) or (QUICK_SEGMENTS if options.quick else SEGMENTS)
    program = dense_spiral(segments)
    f = stream_run(program)
    print(f"dense CAM: {f['segments']} segments of {FEED_M_S * TICK_S * 1e6:.1f} um at 1300 mm/min, T = 1 ms on "
          f"the wall clock, window {WINDOW}, planned ahead of the tool in a {bench_config().stream_planner} "
          f"(first chunk "
          f"{f['plan_cpu_s']:.3f} s CPU); load {f['load_1min']:.1f}")
    print(format_table(
        ["ticks", "tick p50 us", "p99.9 us", "max us", f"> {TICK_BUDGET_S * 1e3:g} ms", "waited for plan",
         "feed/programmed min", "held start", "held max 1st half", "2nd half", "end", "0 waits", "feed >= 90 %",
         "memory flat"],
        [[f["ticks"], round(f["tick_p50_s"] * 1e6, 1), round(f["tick_p999_s"] * 1e6, 1),
          round(f["tick_max_s"] * 1e6, 1), f["late_ticks"], f["planner_waits"], round(f["feed_ratio_min"], 4),
          f["held_start"], f["held_max_first_half"], f["held_max_second_half"], f["held_end"],
          goal_text(f["planner_waits"] == 0), goal_text(f["feed_ratio_min"] >= FEED_GOAL),
          goal_text(f["held_max_second_half"] <= f["held_max_first_half"])]]))
    j = stream_run(program, jerk=True)
    print(f"the same with the jerk limit {limits_for(program, True).max_jerk_m_s3} m/s^3, jerk_mode "
          f"{j['jerk_mode']} (first chunk {j['plan_cpu_s']:.3f} s CPU); load {j['load_1min']:.1f}")
    print(format_table(
        ["ticks", "tick p50 us", "max us", "waited for plan", "feed/programmed min", "held start",
         "held max 1st half", "2nd half", "end", "v ratio", "a ratio", "jerk ratio", "dev / P checked",
         f"every {DEVIATION_STRIDE}th", "chunks re-planned",
         "over P", "0 waits", "feed >= 90 %", "memory flat", "limits, P"],
        [[j["ticks"], round(j["tick_p50_s"] * 1e6, 1), round(j["tick_max_s"] * 1e6, 1), j["planner_waits"],
          round(j["feed_ratio_min"], 4), j["held_start"], j["held_max_first_half"], j["held_max_second_half"],
          j["held_end"], round(j["velocity_ratio"], 4), round(j["acceleration_ratio"], 4), round(j["jerk_ratio"], 4),
          round(j["checked_deviation_over_p"], 4), round(j["deviation_over_p"], 4), j["replanned_chunks"],
          j["over_tolerance_chunks"],
          goal_text(j["planner_waits"] == 0), goal_text(j["feed_ratio_min"] >= FEED_GOAL),
          goal_text(j["held_max_second_half"] <= j["held_max_first_half"]),
          goal_text(max(j["velocity_ratio"], j["acceleration_ratio"], j["jerk_ratio"]) <= 1.0 + 1e-9
                    and max(j["deviation_over_p"], j["checked_deviation_over_p"]) <= 1.0)]]))
    run_dir = Path(getattr(options, "out", None) or project_root() / "bags" / "bench" / "blending" / timestamp())
    runs = [graph_run(program, run_dir / "dense_cam_stream"),
            graph_run(program, run_dir / "dense_cam_stream_jerk", jerk=True),
            graph_run(program, run_dir / "dense_cam_stream_jerk_thread", jerk=True, planner="thread"),
            graph_run(program, run_dir / "dense_cam_whole", 10**9)]
    print(format_table(["composed graph (loop), real time, T = 1 ms", "status", "ticks", "simulated s",
                        "mean period ms", "late commands", "late share", "waited for plan",
                        "held rows first/max/last", "child's rows first/max/last", "load (1 min)",
                        "0 late from planning", "1 kHz held"],
                       [[_graph_label(g), g["graph_status"], g["graph_ticks"],
                         round(g["graph_simulated_s"], 2), round(g["graph_mean_period_s"] * 1e3, 3),
                         g["graph_late_commands"], round(g["graph_late_share"], 5),
                         "-" if g["graph_planner_waits"] is None else g["graph_planner_waits"],
                         "-" if g["graph_held_rows"] is None else "/".join(map(str, g["graph_held_rows"])),
                         "-" if g["graph_child_held_rows"] is None else "/".join(map(str, g["graph_child_held_rows"])),
                         round(g["graph_load_1min"], 1),
                         goal_text(g["graph_status"] == "finished" and not g["graph_planner_waits"]),
                         goal_text(g["graph_status"] == "finished" and g["graph_late_commands"] == 0
                                   and g["graph_mean_period_s"] <= PERIOD_HELD * TICK_S)] for g in runs]))
    for g in runs:
        if g["graph_faults"]:
            print(f"  faults (window {g['graph_window']}): {g['graph_faults']}")
    return {**f, "jerk": j, "graph": runs}
