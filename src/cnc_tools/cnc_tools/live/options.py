"""The ``--live`` options of ``cnc-contour run`` and ``replay``, and the live server they start.

``--live`` serves the run on ``ws://127.0.0.1:8765`` (``--live-port N``; another address only with
``--live-host``, warned about on stderr); ``--live-rate R`` paces an engine run at R simulated seconds per wall
second; ``--live-linger S`` keeps the server up S seconds after the run's end, so a viewer gets the last
windows before the command goes on (scores, plots) and exits.
"""
from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from cnc_contour_control.core import topics
from cnc_contour_control.core.errors import ConfigError
from cnc_tools.live.decimate import WINDOW_NS
from cnc_tools.live.server import DEFAULT_HOST, DEFAULT_PORT, LiveConfig, LiveServer
from cnc_tools.runs.scenario import Scenario

if TYPE_CHECKING:
    from cnc_tools.bagio.playback import PlaybackControl
    from cnc_tools.live.feed import LiveFeed

#: Default of --live-linger, s.
LINGER_S = 1.0


def add_live_arguments(parser: argparse.ArgumentParser, rate: bool = True) -> None:
    """``--live``, ``--live-port``, ``--live-host``, ``--live-linger`` (and ``--live-rate`` when ``rate``)."""
    parser.add_argument("--live", action="store_true",
                        help=f"serve the run to Foxglove or Lichtblick on ws://{DEFAULT_HOST}:{DEFAULT_PORT} "
                             "(docs/live.md)")
    parser.add_argument("--live-port", type=int, default=DEFAULT_PORT, metavar="N",
                        help=f"port of the live server (default {DEFAULT_PORT}; 0: any free one)")
    parser.add_argument("--live-host", default=DEFAULT_HOST, metavar="ADDRESS",
                        help=f"address of the live server (default {DEFAULT_HOST}; another one is reachable from "
                             "other machines and said loudly)")
    parser.add_argument("--live-linger", type=float, default=LINGER_S, metavar="S",
                        help=f"keep the live server up S seconds after the run (default {LINGER_S:g})")
    if rate:
        parser.add_argument("--live-rate", type=float, default=1.0, metavar="R",
                            help="with --engine --live: simulated seconds per wall second (default 1: real time)")


def open_server(args: argparse.Namespace, **extensions: Any) -> LiveServer:
    """The live server the options ask for (``extensions``: listener, capabilities, ... of :class:`LiveServer`)."""
    if not 0.0 <= args.live_linger <= 3600.0:
        raise ConfigError(f"--live-linger must be in [0, 3600] s, got {args.live_linger}")
    server = LiveServer(LiveConfig(host=args.live_host, port=args.live_port), **extensions)
    print(f"live: serving on {server.url} (Foxglove or Lichtblick: open connection, Foxglove WebSocket; "
          "layout: src/cnc_tools/cnc_tools/live/layout.json)", flush=True)
    return server


def window_ns(rate: float) -> int:
    """The decimation window in stamp time: 20 ms at real time, scaled with the pace (<= 100 samples per wall s)."""
    return int(WINDOW_NS * max(1.0, rate))


@contextmanager
def live_session(args: argparse.Namespace, rate: float = 1.0, **extensions: Any) -> Iterator[LiveFeed]:
    """A server and its feed for one command; closed (after ``--live-linger``) however the command ends."""
    from cnc_tools.live.feed import LiveFeed  # foxglove: loaded only with --live

    server = open_server(args, **extensions)
    feed = LiveFeed(server, window_ns(rate))
    try:
        yield feed
    finally:
        try:
            feed.finish(time.time_ns())
            time.sleep(args.live_linger)
        finally:
            server.close()


@contextmanager
def engine_live(args: argparse.Namespace, scenario: Scenario,
                **extensions: Any) -> Iterator[dict[str, Callable[..., None]]]:
    """The engine's options for ``run --engine``: ``{"on_tick": observer}`` with --live, else nothing; the viewer
    may set gains and publish overrides (``live/talkback.py``; ``extensions``: :class:`LiveServer`'s listener,
    capabilities, ... instead)."""
    if not getattr(args, "live", False):
        yield {}
        return
    from foxglove.messages import LogLevel

    from cnc_tools.live.engine import check_rate
    from cnc_tools.live.talkback import EngineTalkback, TalkingEngineLive

    rate = check_rate(args.live_rate)
    talkback = EngineTalkback(scenario)  # the viewer's parameters and client publish (live/talkback.py)
    with live_session(args, rate, **{**talkback.server_options(), **extensions}) as feed:
        talkback.attach(feed.server)
        observer = TalkingEngineLive(scenario, feed, rate, talkback=talkback)
        observer.start()
        try:
            yield {"on_tick": observer}
        except Exception as err:
            feed.note(LogLevel.Error, f"run ended: {err}", time.time_ns(), name="engine")
            raise
        feed.note(LogLevel.Info, "run finished", time.time_ns(), name="engine")


@dataclass(frozen=True)
class GraphLive:
    """What a graph run needs from --live: the extra reader every stage waits for, and the feed (None without)."""

    extra_subscribers: int = 0
    feed: LiveFeed | None = None


@contextmanager
def graph_live(args: argparse.Namespace, namespace: str, scenario: Scenario,
               **extensions: Any) -> Iterator[GraphLive]:
    """For a graph run: with --live, a ``live`` node in this process reads the run's namespace and every stage
    waits for it (one extra subscriber), so the viewer sees every tick; the run's channels are offered at once."""
    if not getattr(args, "live", False):
        yield GraphLive()
        return
    import os

    from cnc_tools.live.ros import LiveThread, RosBus
    from cnc_tools.live.talkback import GraphTalkback
    from cnc_tools.runs.dds import apply_loopback_policy

    apply_loopback_policy(os.environ)  # this process's reader joins the run's domain, on loopback as the nodes
    talkback = GraphTalkback(scenario)  # the viewer's parameters and client publish, onto the run's nodes
    with live_session(args, **{**talkback.server_options(), **extensions}) as feed:
        talkback.attach(feed.server)
        for name, type_name in scenario.pipeline().recorded_topics().items():
            if type_name != topics.CLOCK.type_name:
                feed.advertise(name, type_name)
        thread = LiveThread(feed, namespace)
        talkback.bus = RosBus(thread.node)
        try:
            yield GraphLive(1, feed)
        finally:
            talkback.close()
            thread.close()


@contextmanager
def replay_live(args: argparse.Namespace, recorded: Mapping[str, str], control: PlaybackControl | None = None,
                **extensions: Any) -> Iterator[int]:
    """For ``replay --live``: a ``live`` node in this process on the bag's run namespace, its topics (``recorded``:
    name -> type) offered at once; yields the readers the replay waits for on each topic (at least this one).
    ``control``: the replay's playback control, offered to the viewer (``live/playback.py``)."""
    if not getattr(args, "live", False):
        yield int(args.wait_for_subscribers)
        return
    from cnc_tools.bagio.recording import run_namespace
    from cnc_tools.live.playback import ReplayPlayback
    from cnc_tools.live.ros import LiveThread

    namespace = run_namespace(recorded)
    playback = None if control is None else ReplayPlayback(control)
    if playback is not None:
        extensions = {**playback.server_options(), **extensions}
    with live_session(args, float(getattr(args, "rate", 1.0)), **extensions) as feed:
        if playback is not None:
            playback.attach(feed.server)
        for name, type_name in recorded.items():
            if type_name != topics.CLOCK.type_name:
                diagnostics = type_name == topics.DIAGNOSTICS.type_name
                feed.advertise(topics.DIAGNOSTICS.name if diagnostics else topics.relative(namespace, name), type_name)
        thread = LiveThread(feed, namespace, time.time_ns if playback is None else playback.log_time_ns)
        try:
            yield max(1, int(args.wait_for_subscribers))
        finally:
            thread.close()
