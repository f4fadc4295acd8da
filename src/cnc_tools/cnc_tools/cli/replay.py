"""``cnc-contour replay BAG``: republish a recorded run with its recorded timing, as ``ros2 bag play`` would."""
from __future__ import annotations

import argparse
from pathlib import Path

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.bagio.replay import Recording, ReplayConfig, ReplaySchedule, load_recording


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
                        help="start once every replayed topic has N readers (default 0: at once)")


def replay(args: argparse.Namespace) -> int:
    """Replay a bag; exit 0 when done, 1 if the bag was damaged (its prefix was replayed), 3 on a fault."""
    if not 0 <= args.wait_for_subscribers <= 1000:
        raise ConfigError(f"--wait-for-subscribers must be in [0, 1000], got {args.wait_for_subscribers}")
    config = ReplayConfig(rate=args.rate, start_offset_s=args.start_offset, loop=args.loop, topics=tuple(args.topics),
                          skip_empty_s=args.skip_empty)
    recording = load_recording(args.bag, config.topics)
    schedule = ReplaySchedule(recording, config)  # refuses a start offset past the end before any DDS starts
    print(f"replaying {recording.describe()}\n  {schedule.describe()}", flush=True)
    code = _spin(recording, config, args.wait_for_subscribers)
    if code == 0 and not recording.integrity.complete:
        return 1
    return code


def _spin(recording: Recording, config: ReplayConfig, min_subscribers: int) -> int:
    """Run the replay node in this process until the replay ends (rclpy is imported only here)."""
    from rclpy.parameter import Parameter

    from cnc_contour_control.nodes.common import spin_node
    from cnc_tools.nodes.replay_node import ReplayNode

    overrides = [Parameter("bag", value=str(recording.source)), Parameter("rate", value=float(config.rate)),
                 Parameter("start_offset_s", value=float(config.start_offset_s)), Parameter("loop", value=config.loop),
                 Parameter("topics", value=list(config.topics) or [""]),
                 Parameter("skip_empty_s", value=float(config.skip_empty_s)),
                 Parameter("min_subscribers", value=int(min_subscribers))]
    return spin_node(lambda: ReplayNode(recording, namespace="/cnc", parameter_overrides=overrides), [])
