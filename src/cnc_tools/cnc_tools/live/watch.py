"""Watch an engine run through the live server as a viewer would: for the tests and ``cnc-contour bench live``.

:func:`watch_engine_run` starts the server (any free port on loopback), connects a :class:`LiveClient`,
subscribes to the chosen channels before the first tick, runs the engine paced (``run --engine --live``'s
path: :func:`~cnc_tools.live.options.engine_live` and ``run_on_engine``), and collects every message until
the server closes. The server and the client are closed however it ends.
"""
from __future__ import annotations

import argparse
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import CncError
from cnc_tools.live.client import LiveClient, Received
from cnc_tools.live.options import engine_live
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.backends import run_on_engine
from cnc_tools.runs.scenario import Scenario

#: Seconds the server stays up after the run, for the last windows to leave.
LINGER_S = 0.5


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


def watch_engine_run(scenario: Scenario, run_dir: Path, topics: Sequence[str], rate: float = 1.0,
                     timeout_s: float = 120.0) -> Watched:
    """Run ``scenario`` on the engine with --live into ``run_dir``, watched on ``topics`` (all when empty)."""
    outcome: dict[str, Any] = {}
    with engine_live(live_args(rate), scenario) as live:
        url = live["on_tick"].feed.server.url  # type: ignore[attr-defined]  # the observer is an EngineLive
        client = LiveClient(url)
        try:
            client.wait_channels(topics or ("/cnc/joint_states",))  # every channel of the run is advertised at once
            channels = dict(client.channels)
            client.subscribe(topics or sorted(channels))
            collector = threading.Thread(target=client.collect, args=(lambda _: False, timeout_s), daemon=True)
            collector.start()
            outcome["record"] = run_on_engine(scenario, run_dir, **live)
        except BaseException:
            client.close()
            raise
    collector.join(timeout_s)  # the server closed after its linger: the client saw the end
    client.close()
    if collector.is_alive():
        raise CncError(f"the live client did not see the server close within {timeout_s} s")
    return Watched(channels, client.pending, outcome["record"])
