"""The live view: peak-keeping decimation, the server's address rule, and an engine run watched by a protocol client.

The client (``cnc_tools.live.client``, websockets, no browser) subscribes before the first tick of a paced engine
run at T = 1 ms and gets, sample for sample, the bag's ``contour_error`` messages (the same CDR bytes), the
scorer's exact contour error, and peak streams that keep the bag's contour-error peak exactly.
"""
from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.scoring import contour_error_series
from cnc_tools.bagio.bag import read_bag
from cnc_tools.bagio.typestore import project_typestore
from cnc_tools.live.cdr import CdrTemplate
from cnc_tools.live.decimate import WINDOW_NS, LastInWindow, PeakDecimator
from cnc_tools.live.engine import check_rate
from cnc_tools.live.layout import LAYOUT_PATH, build_layout, layout_topics
from cnc_tools.live.server import LiveConfig, LiveServer
from cnc_tools.live.watch import Watched, watch_engine_run
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SCENARIO = ROOT / "scenarios" / "paper001_circle.yaml"
CHANNELS = ("/cnc/joint_states", "/cnc/reference", "/cnc/contour_error", "/cnc/servo/x/command",
            "/live/contour_error/exact", "/live/contour_error/exact/peaks", "/live/contour_error/estimated/peaks",
            "/live/servo/x/peaks", "/live/scene", "/live/log", "/live/feed_override", "/live/xy")
PROPERTY = settings(max_examples=40, deadline=None)


# --------------------------------------------------------------------------- decimation
@PROPERTY
@given(st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=1, max_size=300), st.integers(1, 50))
def test_the_peak_streams_keep_every_window_extreme_and_send_at_most_two_per_window(values: list[float],
                                                                                   per_window: int) -> None:
    decimator = PeakDecimator[tuple[int, float]](window_ns=per_window)
    kept = [s for k, v in enumerate(values) for s in decimator.push(k, v, (k, v))] + decimator.flush()
    for window in range(0, len(values), per_window):
        chunk = values[window:window + per_window]
        in_window = [v for k, v in kept if window <= k < window + per_window]
        assert min(chunk) in in_window and max(chunk) in in_window and len(in_window) <= 2
    assert [k for k, _ in kept] == sorted(k for k, _ in kept)


@PROPERTY
@given(st.lists(st.integers(-5, 5), min_size=1, max_size=200), st.integers(1, 30),
       st.lists(st.integers(1, 40), min_size=1, max_size=20))
def test_batches_keep_the_samples_one_by_one_pushes_keep(values: list[int], per_window: int, cuts: list[int]) -> None:
    one, many = PeakDecimator[int](per_window), PeakDecimator[int](per_window)
    last_one, last_many = LastInWindow[int](per_window), LastInWindow[int](per_window)
    expected = [(p, k) for k, v in enumerate(values) for p in one.push(k, v, k)]  # (payload, closing sample)
    expected_last = [(p, k) for k in range(len(values)) for p in last_one.push(k, k)]
    got: list[tuple[int, int]] = []
    got_last: list[tuple[int, int]] = []
    start = 0
    for size in [*cuts, len(values)]:  # batches of the given sizes, the rest in one
        stamps = np.arange(start, min(start + size, len(values)))
        if stamps.size:
            payload = stamps.tolist().__getitem__  # sample i of the batch: its stamp
            got += [(p, start + i) for p, i in many.push_many(stamps, np.array(values, float)[stamps], payload)]
            got_last += [(p, start + i) for p, i in last_many.push_many(stamps, payload)]
        start += size
    assert got == expected and many.flush() == one.flush()  # ties: the first of equal values, as push
    assert got_last == expected_last and last_many.flush() == last_one.flush()


def test_cdr_templates_write_the_bytes_rosbags_writes() -> None:
    store, values, k = project_typestore(), np.random.default_rng(7).normal(size=(5, 13)), np.arange(5)
    kind, types = "cnc_contour_interfaces/msg/Reference", project_typestore().types

    def message(i: int) -> object:
        header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](
            sec=i, nanosec=999_999_000 + i), frame_id="machine")
        v = values[i]
        return types[kind](header=header, axis_names=["x", "y", "z"], position_m=v[0:3], velocity_m_s=v[3:6],
                           acceleration_m_s2=v[6:9], path_length_m=float(v[9]), segment_index=i * 7,
                           feed_m_s=float(v[10]), programmed_feed_m_s=float(v[11]), feed_override_ratio=float(v[12]),
                           done=bool(i % 2))

    rows = CdrTemplate(store, kind, message(0)).fill(5, {
        "header.stamp.sec": k, "header.stamp.nanosec": 999_999_000 + k, "position_m": values[:, 0:3],
        "velocity_m_s": values[:, 3:6], "acceleration_m_s2": values[:, 6:9], "path_length_m": values[:, 9],
        "segment_index": k * 7, "feed_m_s": values[:, 10], "programmed_feed_m_s": values[:, 11],
        "feed_override_ratio": values[:, 12], "done": k % 2})
    assert [row.tobytes() for row in rows] == [bytes(store.serialize_cdr(message(i), kind)) for i in range(5)]


def test_bad_live_options_name_the_option_the_bound_and_the_value() -> None:
    with pytest.raises(ConfigError, match=r"--live-port must be in \[0, 65535\], got 70000"):
        LiveConfig(port=70000)
    with pytest.raises(ConfigError, match=r"--live-rate must be in \[0.01, 1000\], got 0"):
        check_rate(0.0)
    with pytest.raises(ConfigError, match="window_ns must be > 0, got 0"):
        PeakDecimator(0)


def test_only_another_address_than_loopback_is_warned_about() -> None:
    warned = io.StringIO()
    with LiveServer(LiveConfig(port=0), warn=warned):
        pass
    assert warned.getvalue() == ""
    with LiveServer(LiveConfig(host="0.0.0.0", port=0), warn=warned) as server:
        assert server.port > 0
    assert "WARNING" in warned.getvalue() and "NOT loopback" in warned.getvalue()


def test_a_port_in_use_is_a_usage_error_naming_it() -> None:
    with LiveServer(LiveConfig(port=0)) as first:
        with pytest.raises(ConfigError, match=f"--live-port {first.port} .*in use"):
            LiveServer(LiveConfig(port=first.port))


# --------------------------------------------------------------------------- an engine run, watched
@pytest.fixture(scope="module")
def watched(tmp_path_factory: pytest.TempPathFactory) -> Watched:
    """paper 001's circle with the window estimator, 0.4 s at T = 1 ms, paced in real time and watched."""
    scenario = load_scenario(SCENARIO, {"duration_s": 0.4, "estimator": {"method": "window"}})
    return watch_engine_run(scenario, tmp_path_factory.mktemp("live") / "run", CHANNELS)


def _bag_raw(bag: Path, topic: str) -> list[bytes]:
    with AnyReader([bag], default_typestore=project_typestore()) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        return [bytes(raw) for _, _, raw in reader.messages(connections=connections)]


def test_ros_channels_carry_the_bags_ros2msg_schemas(watched: Watched) -> None:
    with open(next((watched.record.source / "bag").glob("*.mcap")), "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    in_bag = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
    for topic in ("/cnc/joint_states", "/cnc/reference", "/cnc/contour_error", "/cnc/servo/x/command"):
        channel, schema = watched.channels[topic], in_bag[topic]
        assert (channel["encoding"], channel["schemaEncoding"]) == ("cdr", "ros2msg")
        assert (channel["schemaName"], channel["schema"]) == (schema.name, schema.data.decode())


def test_contour_error_messages_are_the_bags_sample_for_sample(watched: Watched) -> None:
    bag = watched.record.source / "bag"
    for topic in ("/cnc/contour_error", "/cnc/joint_states", "/cnc/servo/x/command"):
        live = [r.payload for r in watched.of(topic)]
        assert len(live) == watched.record.summary["ticks"] == 401
        assert live == _bag_raw(bag, topic), topic


def test_the_exact_contour_error_is_the_scorers_and_its_peak_stream_keeps_the_peak(watched: Watched) -> None:
    series, _ = contour_error_series(read_bag(watched.record.source / "bag"))
    exact = [r.json() for r in watched.of("/live/contour_error/exact")]
    live = {m["stamp_ns"]: m["contour_error_um"] for m in exact}
    scored = dict(zip(series.stamp_ns.tolist(), (series.error_m * 1e6).tolist()))
    assert scored and all(live[stamp] == value for stamp, value in scored.items())
    peaks = [r.json() for r in watched.of("/live/contour_error/exact/peaks")]
    assert max(abs(p["contour_error_um"]) for p in peaks) == max(abs(v) for v in live.values())
    per_window = np.bincount([p["stamp_ns"] // WINDOW_NS for p in peaks])
    assert per_window.max() <= 2 and len(peaks) < len(live) / 5  # <= 100 per simulated second at T = 1 ms


def test_the_estimated_peak_stream_keeps_the_bags_estimated_peak(watched: Watched) -> None:
    estimate = watched.record.contour_error
    assert estimate is not None
    peaks = [r.json()["contour_error_um"] for r in watched.of("/live/contour_error/estimated/peaks")]
    assert max(map(abs, peaks)) == float(np.abs(estimate.contour_error_m * 1e6).max())


def test_the_scene_draws_the_program_and_the_run_paces_at_real_time(watched: Watched) -> None:
    assert watched.of("/live/scene") and watched.of("/live/log")
    stamps = [r.arrived_ns for r in watched.of("/cnc/joint_states")]
    assert 0.3 <= (stamps[-1] - stamps[0]) * 1e-9 <= 5.0  # 0.4 s simulated at rate 1 (the load may add)


def test_the_shipped_layout_is_current_and_names_only_advertised_channels(watched: Watched) -> None:
    shipped = json.loads(LAYOUT_PATH.read_text(encoding="utf-8"))
    assert shipped == build_layout(), "python -m cnc_tools.live.layout writes it again"
    named = layout_topics(shipped)
    assert {"/live/xy", "/live/contour_error/exact/peaks", "/live/log", "/live/feed_override"} <= named
    assert named <= set(watched.channels), sorted(named - set(watched.channels))


def test_the_override_channel_shows_the_schedules_request_and_the_applied_ratio(tmp_path: Path) -> None:
    scenario = load_scenario(ROOT / "scenarios" / "feed_hold_circle.yaml")  # 100 % -> 50 % -> hold -> 100 %
    watched = watch_engine_run(scenario, tmp_path / "run", ("/live/feed_override",), rate=5.0)
    samples = [r.json() for r in watched.of("/live/feed_override")]
    requested = {m["requested_ratio"] for m in samples}
    assert {0.0, 0.5, 1.0} <= requested, sorted(requested)
    applied = [m["applied_ratio"] for m in samples]
    assert min(applied) == 0.0 and applied[-1] == 1.0 and 0.0 < max(applied) <= 1.0
