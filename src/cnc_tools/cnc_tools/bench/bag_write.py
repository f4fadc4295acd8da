"""Bench ``bag-write``: the recorder's message path, rosbags + the ``mcap`` library against our MCAP writer.

One run writes the same messages twice, in rotated order over the rounds:

- ``library``: :class:`LibraryBagWriter`, the path before issue 9 (``rosbags.rosbag2.Writer.write``
  -> :class:`~cnc_tools.bagio.mcap_storage.LibraryMcapStorage` -> ``mcap.writer.Writer.add_message``);
- ``ours``: :class:`~cnc_tools.bagio.bag.BagWriter` (its direct path ->
  :class:`~cnc_tools.bagio.mcap_writer.McapWriter`).

The messages are the real CDR of a synthetic 1 kHz 2-axis circle run
(:func:`cnc_tools.bagio.synthetic.write_run_bag`: clock, joint_states,
reference, two axis commands per tick), repeated to :data:`MESSAGES`. The
figures are the medians over the rounds of the wall time per message
(construction to close) and the ratio; the two files are checked to be
byte-identical.
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from mcap.reader import make_reader
from rosbags.rosbag2 import StoragePlugin, Writer

from cnc_contour_control.core.errors import BagError
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.bagio.bag import BagWriter
from cnc_tools.bagio.mcap_storage import LibraryMcapStorage
from cnc_tools.bagio.synthetic import circle_program, circle_trajectory, write_run_bag

#: Messages written per side and round (10 s of a 1 kHz 2-axis run at 5 messages per tick).
MESSAGES = 50_000
ROUNDS = 5
#: One message: topic, log time [ns], CDR bytes.
Message = tuple[str, int, bytes]


class _LibraryRosbagWriter(Writer):
    """rosbags' rosbag2 writer on :class:`LibraryMcapStorage`."""

    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: LibraryMcapStorage}


class LibraryBagWriter(BagWriter):
    """:class:`BagWriter` writing each message through rosbags and the ``mcap`` library (the old path)."""

    _ROSBAG_WRITER = _LibraryRosbagWriter

    def write(self, topic: str, timestamp_ns: int, cdr_bytes: bytes | memoryview) -> None:
        """Append one message through ``rosbags.rosbag2.Writer.write``."""
        if self._writer is None or topic not in self._connections:
            raise BagError(f"bag {self.path}: cannot write {topic!r} (closed or not declared)")
        self._writer.write(self._connections[topic], int(timestamp_ns), cdr_bytes)
        self._direct[topic][2][0] += 1


def run_messages(folder: Path, n_messages: int) -> tuple[dict[str, str], list[Message]]:
    """Topics and ``n_messages`` messages of a synthetic 1 kHz 2-axis run (its real CDR), repeated in time."""
    bag = write_run_bag(folder / "source", circle_program(), circle_trajectory(0.02, 5e-6, n=1000))
    with (bag / "source.mcap").open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None
        topics = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        one = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages() if m.log_time > 0]
    span_ns = one[-1][1] - one[0][1] + 1_000_000
    return topics, [(t, stamp + (k // len(one)) * span_ns, data)
                    for k, (t, stamp, data) in ((k, one[k % len(one)]) for k in range(n_messages))]


def write_all(kind: type[BagWriter], path: Path, topics: dict[str, str],
              messages: Sequence[Message]) -> tuple[float, float]:
    """Write ``messages`` to a new bag with ``kind``; wall times [s] of the writes alone and of open to close."""
    start_s = time.perf_counter()
    with kind(path, topics) as bag:
        loop_start_s = time.perf_counter()
        for topic, stamp_ns, data in messages:
            bag.write(topic, stamp_ns, data)
        loop_s = time.perf_counter() - loop_start_s
    return loop_s, time.perf_counter() - start_s


def bag_write_bench(options: argparse.Namespace) -> int:
    """Time both paths over the rounds; print us per message and the ratio; 1 if the files differ."""
    n_messages, rounds = (MESSAGES // 10, 2) if options.quick else (MESSAGES, ROUNDS)
    sides: dict[str, type[BagWriter]] = {"library": LibraryBagWriter, "ours": BagWriter}
    times_s: dict[str, list[tuple[float, float]]] = {name: [] for name in sides}
    load_at_start = machine()["load_average_1min"]
    with tempfile.TemporaryDirectory() as tmp:
        topics, messages = run_messages(Path(tmp), n_messages)
        for r in range(rounds):
            names = list(sides)[r % 2:] + list(sides)[:r % 2]
            for name in names:
                times_s[name].append(write_all(sides[name], Path(tmp) / name / f"run{r}", topics, messages))
        identical = all((Path(tmp) / "library" / f"run{r}" / f"run{r}.mcap").read_bytes()
                        == (Path(tmp) / "ours" / f"run{r}" / f"run{r}.mcap").read_bytes() for r in range(rounds))
    us = {name: [1e6 * statistics.median(t[i] for t in runs) / n_messages for i in (0, 1)]
          for name, runs in times_s.items()}
    print(f"bag-write: {n_messages} messages ({len(topics)} topics), {rounds} rounds; "
          f"load 1 min {load_at_start:.2f} -> {machine()['load_average_1min']:.2f}")
    print(format_table(["path", "us/message (writes)", "ratio", "us/message (open to close)", "ratio"],
                       [[name, round(us[name][0], 2), round(us[name][0] / us["library"][0], 3),
                         round(us[name][1], 2), round(us[name][1] / us["library"][1], 3)] for name in sides]))
    print(f"files byte-identical: {identical}")
    write_json(options.json, {"bench": "bag-write", "messages": n_messages, "rounds": rounds, "us_per_message": us,
                              "identical": identical, "machine": machine(), "load_at_start": load_at_start})
    return 0 if identical else 1
