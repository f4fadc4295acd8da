"""Watch an engine run through the live server as a viewer would: for the tests and ``cnc-contour bench live``.

:func:`watch_engine_run` starts the server (any free port on loopback), connects a :class:`LiveClient`,
subscribes to the chosen channels before the first tick, runs the engine paced (``run --engine --live``'s
path: :func:`~cnc_tools.live.options.engine_live` and ``run_on_engine``), and collects every message until
the server closes. The server and the client are closed however it ends.
"""
from __future__ import annotations

import argparse
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import CncError
from cnc_tools.live.client import LiveClient, Received
from cnc_tools.live.options import engine_live
from cnc_tools.live.server import LiveServer
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.backends import run_on_engine
from cnc_tools.runs.scenario import Scenario

#: Seconds the server stays up after the run, for the last windows to leave.
LINGER_S = 0.5
#: How often the collector looks whether the server has its subscriptions, s.
SUBSCRIBE_POLL_S = 0.005


@dataclass(frozen=True)
class Watched:
    """What the viewer got: the channels advertised (topic -> channel), the messages, and the run's record."""

    channels: dict[str, dict[str, Any]]
    received: list[Received]
    record: RunRecord

    def of(self, topic: str) -> list[Received]:
        """The messages of one channel, in arrival order."""
        return [r for r in self.received if r.topic == topic]


def live_args(rate: float = 1.0, port: int = 0) -> argparse.Namespace:
    """The options ``run --engine --live --live-port PORT --live-rate RATE`` parse to."""
    return argparse.Namespace(live=True, live_port=port, live_host="127.0.0.1", live_linger=LINGER_S,
                              live_rate=rate)


class _Collector:
    """A client subscribed to those of ``topics`` the run offers (all when empty), collecting in a thread until the
    server closes. It returns once ``server`` has every subscription: the run's first tick may follow at once."""

    def __init__(self, server: LiveServer, topics: Sequence[str], timeout_s: float) -> None:
        self.client, self.timeout_s = LiveClient(server.url), timeout_s
        try:
            self.client.wait_channels(("/cnc/joint_states",))  # a run's channels are offered at once
            self.channels = dict(self.client.channels)
            chosen = [t for t in topics if t in self.channels] if topics else sorted(self.channels)
            self.client.subscribe(chosen)
            deadline = time.monotonic() + timeout_s
            while not server.subscribed(chosen):
                if time.monotonic() > deadline:
                    raise CncError(f"the live server did not take the subscriptions to {len(chosen)} channels "
                                   f"within {timeout_s} s")
                time.sleep(SUBSCRIBE_POLL_S)
        except BaseException:
            self.client.close()
            raise
        self.thread = threading.Thread(target=self.client.collect, args=(lambda _: False, timeout_s), daemon=True)
        self.thread.start()

    def finish(self) -> list[Received]:
        """Wait until the server closed (after its linger), close the client, return what it got."""
        self.thread.join(self.timeout_s)
        self.client.close()
        if self.thread.is_alive():
            raise CncError(f"the live client did not see the server close within {self.timeout_s} s")
        return self.client.pending


def watch_graph_run(scenario: Scenario, run_dir: Path, topics: Sequence[str], timeout_s: float = 300.0) -> Watched:
    """Run ``scenario`` through the node graph with --live into ``run_dir`` (``run --live``'s path), watched."""
    from cnc_tools.bagio.bag import read_bag
    from cnc_tools.live.options import graph_live
    from cnc_tools.runs.graph import run_graph
    from cnc_tools.runs.namespaces import run_namespace

    namespace = run_namespace()
    with graph_live(live_args(), namespace, scenario) as live:
        assert live.feed is not None  # --live is set
        collector = _Collector(live.feed.server, topics, timeout_s)
        try:
            result = run_graph(scenario, run_dir, record=True, namespace=namespace,
                               extra_subscribers=live.extra_subscribers, timeout_s=timeout_s)
        except BaseException:
            collector.client.close()
            raise
    received = collector.finish()
    if result.faults or result.bag_path is None:
        raise CncError(f"the watched graph run faulted: {result.faults}")
    record = read_bag(result.bag_path).with_(summary=result.summary, backend="graph", name=scenario.name)
    return Watched(collector.channels, received, record)


def watch_engine_run(scenario: Scenario, run_dir: Path, topics: Sequence[str], rate: float = 1.0,
                     timeout_s: float = 120.0) -> Watched:
    """Run ``scenario`` on the engine with --live into ``run_dir``, watched on ``topics`` (all when empty)."""
    with engine_live(live_args(rate), scenario) as live:
        server = live["on_tick"].feed.server  # type: ignore[attr-defined]  # the observer is an EngineLive
        collector = _Collector(server, topics, timeout_s)
        try:
            record = run_on_engine(scenario, run_dir, **live)
        except BaseException:
            collector.client.close()
            raise
    return Watched(collector.channels, collector.finish(), record)
