"""Bench ``scoring``: offline scoring throughput against a bare rosbags deserialisation loop.

One synthetic run of ``duration_s`` at 1 kHz in 3 axes (joint_states,
reference, /clock, a command per axis: 6 messages per tick) is written once;
then, on the same bag and in the same process:

- the bare loop: rosbags ``AnyReader`` + ``deserialize_cdr`` over every message;
- the scorer: ``read_bag`` + ``score_run`` (CDR decoding included).

Throughput is messages per second over all messages of the bag.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from rosbags.highlevel import AnyReader

from cnc_tools.analysis.scoring import score_run
from cnc_tools.analysis.tables import format_table, goal_text, machine, write_json
from cnc_tools.bagio.bag import read_bag
from cnc_tools.bagio.synthetic import circle_program, circle_trajectory, write_run_bag
from cnc_tools.bagio.typestore import project_typestore

RATIO_GOAL = 0.5
SCORE_TIME_GOAL_S = 1.0


def make_bag(folder: Path, duration_s: float) -> Path:
    """A 3-axis, 1 kHz circle run (R = 20 mm, 5 µm outside) with commands."""
    samples = int(duration_s * 1000)
    return write_run_bag(folder / "run", circle_program(n_axes=3), circle_trajectory(0.02, 5e-6, n=samples, n_axes=3))


def bare_loop_s(bag: Path) -> tuple[float, int]:
    """Wall time of deserialising every message with rosbags, and the message count."""
    store = project_typestore()
    started, count = time.perf_counter(), 0
    with AnyReader([bag], default_typestore=store) as reader:
        for connection, _, raw in reader.messages():
            store.deserialize_cdr(raw, connection.msgtype)
            count += 1
    return time.perf_counter() - started, count


def scoring_s(bag: Path) -> float:
    """Wall time of reading and scoring the bag the way ``cnc-contour score`` does."""
    started = time.perf_counter()
    score_run(read_bag(bag))
    return time.perf_counter() - started


def scoring(options: argparse.Namespace) -> int:
    """Scoring throughput vs the bare rosbags loop, and the time to score a 60 s, 1 kHz, 3-axis run."""
    duration_s = 10.0 if options.quick else 60.0
    with tempfile.TemporaryDirectory() as folder:
        print(f"writing a {duration_s:.0f} s, 1 kHz, 3-axis synthetic run ...", flush=True)
        bag = make_bag(Path(folder), duration_s)
        bare_s, messages = bare_loop_s(bag)
        score_s = min(scoring_s(bag) for _ in range(3))
    ratio = (messages / score_s) / (messages / bare_s)
    rows = [
        ["bare rosbags deserialise loop", messages, round(bare_s, 3), round(messages / bare_s), "", ""],
        ["read_bag + score_run", messages, round(score_s, 3), round(messages / score_s), round(ratio, 2),
         f">= {RATIO_GOAL}: {goal_text(ratio >= RATIO_GOAL)}"],
    ]
    print(format_table(["path", "messages", "wall s", "msg/s", "ratio", "goal"], rows))
    if not options.quick:
        print(f"  time to score the {duration_s:.0f} s run: {score_s:.3f} s "
              f"(goal <= {SCORE_TIME_GOAL_S} s: {goal_text(score_s <= SCORE_TIME_GOAL_S)})")
    write_json(options.json, {"bench": "scoring", "duration_s": duration_s, "messages": messages,
                              "bare_s": bare_s, "score_s": score_s, "throughput_ratio": ratio, "machine": machine()})
    return 0
