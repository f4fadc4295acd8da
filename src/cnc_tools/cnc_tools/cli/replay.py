"""``cnc-contour replay BAG``: republish a recorded run with its recorded timing, as ``ros2 bag play`` would."""
from __future__ import annotations

import argparse
from pathlib import Path

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.topics import CLOCK, DIAGNOSTICS
from cnc_tools.bagio.playback import PlaybackControl, PlaybackRequest
from cnc_tools.bagio.replay import Recording, ReplayConfig, ReplaySchedule, load_recording
from cnc_tools.live.options import add_live_arguments, replay_live

#: Types of the topics a replay does not wait for readers of unless named by --topics: the run's clock and
#: statuses, which no stage of a graph reads (nothing may ever read them).
UNAWAITED_TYPES = frozenset({CLOCK.type_name, DIAGNOSTICS.type_name})
#: Default of --wait-timeout, s.
WAIT_TIMEOUT_S = 30.0


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", type=Path,
                        help="bag folder (or its .mcap file); a damaged bag replays its readable prefix")
    parser.add_argument("--rate", type=float, default=1.0, help="playback speed relative to the recording (default 1)")
    parser.add_argument("--start-offset", type=float, default=0.0, metavar="S",
                        help="start S seconds into the bag (latched topics still get their last message)")
    parser.add_argument("--loop", action="store_true", help="start over at the end, until interrupted")
    parser.add_argument("--skip-empty", type=float, default=10.0, metavar="S",
                        help="skip stretches of log time longer than S seconds with no message (default 10; 0: never)")
    parser.add_argument("--topics", nargs="+", default=[], metavar="TOPIC", help="replay only these topics")
    parser.add_argument("--wait-for-subscribers", type=int, default=0, metavar="N",
                        help="start once each replayed topic has N readers: those of --topics, else every one but "
                             "the clock and /diagnostics (default 0: at once)")
    parser.add_argument("--wait-timeout", type=float, default=WAIT_TIMEOUT_S, metavar="S",
                        help=f"give up (exit 3) when the readers are not there within S seconds "
                             f"(default {WAIT_TIMEOUT_S:g})")
    add_live_arguments(parser, rate=False)
    parser.add_argument("--paused", action="store_true",
                        help="with --live: start paused at the first message; the viewer's play starts it")


def replay(args: argparse.Namespace) -> int:
    """Replay a bag; exit 0 when done, 1 if the bag was damaged (its prefix was replayed), 3 on a fault."""
    if not 0 <= args.wait_for_subscribers <= 1000:
        raise ConfigError(f"--wait-for-subscribers must be in [0, 1000], got {args.wait_for_subscribers}")
    if not 0.01 <= args.wait_timeout <= 1e6:
        raise ConfigError(f"--wait-timeout must be in [0.01, 1000000] s, got {args.wait_timeout}")
    if args.paused and not args.live:
        raise ConfigError("--paused needs --live (only a viewer can start a paused replay)")
    config = ReplayConfig(rate=args.rate, start_offset_s=args.start_offset, loop=args.loop, topics=tuple(args.topics),
                          skip_empty_s=args.skip_empty)
    recording = load_recording(args.bag, config.topics)
    schedule = ReplaySchedule(recording, config)  # refuses a start offset past the end before any DDS starts
    print(f"replaying {recording.describe()}\n  {schedule.describe()}", flush=True)
    awaited = awaited_topics(recording, config.topics)
    if args.wait_for_subscribers:
        print(f"waiting up to {args.wait_timeout:g} s for {args.wait_for_subscribers} reader(s) of each of "
              f"{', '.join(awaited)}", flush=True)
    control = PlaybackControl(schedule.time_range_ns()) if args.live else None  # the viewer's play, pause, seek
    if control is not None and args.paused:
        control.submit(PlaybackRequest(playing=False, speed=config.rate))
    with replay_live(args, recording.topics, control) as readers:
        code = _spin(recording, config, readers, awaited, args.wait_timeout, control)
    if code == 0 and not recording.integrity.complete:
        return 1
    return code


def awaited_topics(recording: Recording, chosen: tuple[str, ...]) -> list[str]:
    """The topics whose readers a replay waits for: the ``chosen`` ones (--topics), else every replayed topic but
    those of :data:`UNAWAITED_TYPES` (all of them if that leaves none)."""
    if chosen:
        return sorted(chosen)
    awaited = sorted(t for t, type_name in recording.topics.items() if type_name not in UNAWAITED_TYPES)
    return awaited or sorted(recording.topics)


def _spin(recording: Recording, config: ReplayConfig, min_subscribers: int, awaited: list[str],
          wait_timeout_s: float, control: PlaybackControl | None = None) -> int:
    """Run the replay node in this process until the replay ends (rclpy is imported only here)."""
    from rclpy.parameter import Parameter

    from cnc_contour_control.nodes.common import spin_node
    from cnc_tools.nodes.replay_node import ReplayNode

    overrides = [Parameter("bag", value=str(recording.source)), Parameter("rate", value=float(config.rate)),
                 Parameter("start_offset_s", value=float(config.start_offset_s)), Parameter("loop", value=config.loop),
                 Parameter("topics", value=list(config.topics) or [""]),
                 Parameter("skip_empty_s", value=float(config.skip_empty_s)),
                 Parameter("min_subscribers", value=int(min_subscribers)),
                 Parameter("wait_topics", value=list(awaited)),
                 Parameter("wait_timeout_s", value=float(wait_timeout_s))]
    return spin_node(lambda: ReplayNode(recording, control, namespace="/cnc", parameter_overrides=overrides), [])
