"""Tier 3: the recorder in a real run: nothing lost, standard files, clean stop, no overwrite."""
from __future__ import annotations

import signal
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import JointState

from cnc_contour_control.core.errors import BagError
from cnc_contour_control.nodes.common import EXIT_FAULT
from cnc_contour_control.testing import TopicProbe
from cnc_tools.bagio.bag import read_bag
from cnc_tools.bagio.typestore import project_typestore
from cnc_tools.runs.engine import tick_count
from cnc_tools.runs.graph import GraphRun, graph_nodes, recorder_spec, run_graph
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
CIRCLE = ROOT / "scenarios" / "paper000_circle_high.yaml"
pytestmark = pytest.mark.e2e


def _mcap(bag: Path) -> Path:
    return next(bag.glob("*.mcap"))


def _raw_by_topic(bag: Path) -> dict[str, list[bytes]]:
    messages: dict[str, list[bytes]] = {}
    with AnyReader([bag], default_typestore=project_typestore()) as reader:
        for connection, _, raw in reader.messages():
            messages.setdefault(connection.topic, []).append(bytes(raw))
    return messages


def test_circle_at_1ms_loses_no_message_and_reads_back_with_rosbags_and_mcap(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE, {"sample_time_s": 0.001, "duration_s": 2.0})  # 2000 ticks
    result = run_graph(scenario, tmp_path, record=True)
    ticks = tick_count(scenario)
    assert result.summary["ticks"] == ticks and result.faults == []
    ns = result.namespace  # the run's own: /cnc/run_<id>, /clock and /diagnostics included
    counts = {topic: len(raw) for topic, raw in _raw_by_topic(result.bag_path).items()}
    for name in ("joint_states", "reference", "servo/x/command", "servo/y/command", "clock"):
        assert counts[f"{ns}/{name}"] == ticks, (name, counts[f"{ns}/{name}"], ticks)
    assert counts[f"{ns}/path"] == 1
    with open(_mcap(result.bag_path), "rb") as stream:
        decoded = Counter(channel.topic for _, channel, _, _ in
                          make_reader(stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
    assert decoded[f"{ns}/joint_states"] == ticks and decoded[f"{ns}/path"] == 1
    run = read_bag(result.bag_path)
    assert run.integrity.complete and run.program.name == "paper000_circle_high"
    with AnyReader([result.bag_path], default_typestore=project_typestore()) as reader:
        end_ns = max(t for c, t, _ in reader.messages() if c.topic == f"{ns}/joint_states")
        diagnostics = [t for c, t, _ in reader.messages() if c.topic == f"{ns}/diagnostics"]
    assert diagnostics and max(diagnostics) <= end_ns, "wall-stamped diagnostics logged inside the run's time"




def test_recorder_closes_the_bag_cleanly_on_sigterm(tmp_path: Path) -> None:
    scenario = load_scenario(CIRCLE)
    bag = tmp_path / "bag"
    nodes = [recorder_spec(scenario, bag), *graph_nodes(scenario, tmp_path, extra_subscribers=2)]
    probed = {"/cnc/joint_states": JointState}
    with TopicProbe(probed) as probe, GraphRun(nodes, tmp_path) as run:
        from cnc_contour_interfaces.msg import AxisCommand, Reference

        for topic, kind in (("/cnc/reference", Reference), ("/cnc/servo/x/command", AxisCommand),
                            ("/cnc/servo/y/command", AxisCommand)):
            probe.node.create_subscription(kind, topic, lambda _m: None, 10)
        # The recorder may trail the probe by a few ticks: wait for a margin above what the bag must hold, and for
        # the recorder's own reader (its stop handler is installed before its node exists: a SIGTERM earlier, to
        # a process still importing, ends it with -15)
        probe.wait_for(lambda: len(probe.received("/cnc/joint_states")) > 60, 30.0, "the run to be going")
        probe.wait_for(lambda: any(info.node_name == "recorder" for info in
                                   probe.node.get_subscriptions_info_by_topic("/cnc/joint_states")),
                       30.0, "the recorder's reader")
        recorder = run.processes["recorder"]
        recorder.send_signal(signal.SIGTERM)
        assert recorder.wait(timeout=20) == 0
    assert (bag / "metadata.yaml").is_file()
    recorded = read_bag(bag)
    assert recorded.integrity.complete, recorded.integrity.describe()
    # how many ticks the recorder took in before the signal depends on the load (it trails the probe); what it
    # promises is that every tick it took in is in the closed bag, from the first on, none skipped
    stamps = recorded.joint_states.stamp_ns
    assert len(stamps) > 0 and np.array_equal(stamps, stamps[0] + 10_000_000 * np.arange(len(stamps))), \
        f"{len(stamps)} ticks, steps {sorted(set(np.diff(stamps).tolist()))[:5]}"
    assert stamps[0] == 0, f"from the run's first tick, not {stamps[0]} ns"


def test_recorder_refuses_an_existing_output_folder(tmp_path: Path) -> None:
    existing = tmp_path / "bag"
    existing.mkdir()
    (existing / "keep.txt").write_text("precious")
    from cnc_tools.runs.graph import find_executable

    result = subprocess.run([str(find_executable("cnc_tools", "recorder")), "--ros-args", "-p", f"output:={existing}"],
                            capture_output=True, text=True, timeout=60)
    output = result.stdout + result.stderr
    assert result.returncode == EXIT_FAULT, output  # the node's fault, not a crash
    assert f"bag folder {existing} exists already" in output, output
    assert (existing / "keep.txt").read_text() == "precious"
    with pytest.raises(BagError):
        read_bag(existing)


#: The seeded runs' namespace: one run after the other, so one namespace for both gives the same topic names.
SEEDED_NS = "/cnc/seeded"


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess[str], Path]:
    """``cnc-contour run`` of the circle for 2 s in SEEDED_NS, as a user types it: its output and run folder."""
    out = tmp_path_factory.mktemp("cli") / "run"
    result = subprocess.run([sys.executable, "-m", "cnc_tools.cli.main", "run", str(CIRCLE), "--out", str(out),
                             "--set", "duration_s=2.0", "--namespace", SEEDED_NS],
                            capture_output=True, text=True, timeout=300)
    return result, out


def test_same_scenario_and_seed_give_the_same_bag_contents(tmp_path: Path,
                                                           cli_run: tuple[subprocess.CompletedProcess[str], Path]
                                                           ) -> None:
    """The graph run again with the CLI run's scenario, seed and namespace records the same messages."""
    result, out = cli_run
    assert result.returncode == 0, result.stdout + result.stderr
    scenario = load_scenario(CIRCLE, {"duration_s": 2.0})
    first = _raw_by_topic(out / "bag")
    second = _raw_by_topic(run_graph(scenario, tmp_path / "b", record=True, namespace=SEEDED_NS).bag_path)
    first.pop(f"{SEEDED_NS}/diagnostics", None), second.pop(f"{SEEDED_NS}/diagnostics", None)  # wall-clock stamps
    assert first.keys() == second.keys() and len(first[f"{SEEDED_NS}/joint_states"]) == tick_count(scenario)
    assert first == second


def test_cnc_contour_run_prints_the_score_and_the_paths(cli_run: tuple[subprocess.CompletedProcess[str], Path]
                                                        ) -> None:
    result, out = cli_run
    assert result.returncode == 0, result.stdout + result.stderr
    for line in ("contour error", "circular test", "bag:", "json:", "plots:"):
        assert line in result.stdout, line
    assert (out / "score.json").is_file() and (out / "bag" / "metadata.yaml").is_file()
    assert len(list((out / "report").glob("*.png"))) >= 4
