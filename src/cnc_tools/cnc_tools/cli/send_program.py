"""``cnc-contour send-program FILE``: run a part program on a running interpolator (RunProgram action).

A G-code file is sent as text (the interpolator may run on another host); any
other file as its absolute path (a YAML program, read by the interpolator).
Feedback is printed as it comes; Ctrl-C cancels the goal (a controlled stop on
the path) and waits for its result. Exit code: 0 completed, 1 rejected or
cancelled, 3 faulted.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.program_file import GCODE_SUFFIXES

#: Result outcome -> exit code (COMPLETED, CANCELED, FAULTED).
EXIT_CODES = {0: 0, 1: 1, 2: 3}


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("program", type=Path, help="G-code (.ngc, .nc, .gcode, .tap, .cnc) or YAML program file")
    parser.add_argument("--action", default="/cnc/run_program", help="the action's name (default /cnc/run_program)")
    parser.add_argument("--feed-mm-min", type=float, default=0.0,
                        help="feed of moves that give none, mm/min (default 0: the program gives every feed)")
    parser.add_argument("--path-tolerance-mm", type=float, default=0.0,
                        help="corner blend tolerance unless the program sets one, mm (default 0: the node's)")
    parser.add_argument("--wait-s", type=float, default=10.0, help="wall time to wait for the server (default 10)")


def goal_of(args: argparse.Namespace) -> Any:
    """The RunProgram goal of the command line (the file's text for G-code, else its absolute path)."""
    from cnc_contour_interfaces.action import RunProgram

    file = args.program
    if not file.is_file():
        raise ConfigError(f"program {str(file)!r} does not exist")
    goal = RunProgram.Goal(program_name=file.stem, feed_mm_min=float(args.feed_mm_min),
                           path_tolerance_mm=float(args.path_tolerance_mm))
    if file.suffix.lower() in GCODE_SUFFIXES:
        goal.gcode = file.read_text()
    else:
        goal.program_file = str(file.resolve())
    return goal


def send_program(args: argparse.Namespace) -> int:
    """Send the goal, print feedback and the result; the exit code of the outcome."""
    import rclpy
    from rclpy.action import ActionClient

    from cnc_contour_interfaces.action import RunProgram

    goal = goal_of(args)
    rclpy.init()
    node = rclpy.create_node("send_program")
    try:
        client = ActionClient(node, RunProgram, args.action)
        if not client.wait_for_server(timeout_sec=args.wait_s):
            raise ConfigError(f"no RunProgram server on {args.action} within --wait-s {args.wait_s} s "
                              f"(is the interpolator running with program_source: action, in this ROS domain?)")
        return _run(node, client, goal)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def _run(node: Any, client: Any, goal: Any) -> int:
    import rclpy

    handle = _wait(node, client.send_goal_async(goal, feedback_callback=FeedbackPrinter()))
    if not handle.accepted:
        print("goal rejected (the interpolator's log and /diagnostics give the reason)", flush=True)
        return 1
    result_future = handle.get_result_async()
    try:
        result = _wait(node, result_future)
    except KeyboardInterrupt:
        print("cancelling: stopping on the path", flush=True)
        handle.cancel_goal_async()
        while rclpy.ok() and not result_future.done():
            rclpy.spin_once(node, timeout_sec=0.1)
        result = result_future.result()
    result = result.result
    print(f"{result.program_name}: {('completed', 'canceled', 'faulted')[result.outcome]} {result.reason}\n"
          f"  max contour error {result.max_contour_error_m * 1e6:.2f} um, "
          f"rms {result.rms_contour_error_m * 1e6:.2f} um,"
          f" max following error {result.max_following_error_m * 1e6:.2f} um\n"
          f"  cycle time {result.cycle_time_s:.3f} s, path {result.path_length_m * 1e3:.3f} of "
          f"{result.total_length_m * 1e3:.3f} mm, {result.ticks} ticks" + (f", bag {result.bag_path}"
                                                                             if result.bag_path else ""), flush=True)
    return EXIT_CODES[int(result.outcome)]


def _wait(node: Any, future: Any) -> Any:
    import rclpy

    while not future.done():
        rclpy.spin_once(node, timeout_sec=0.1)
    return future.result()


class FeedbackPrinter:
    """Prints a goal's feedback, one line per ``period_s`` of wall time at most."""

    def __init__(self, period_s: float = 1.0) -> None:
        self.period_s, self._last_s = period_s, -float("inf")

    def __call__(self, msg: Any) -> None:
        now_s = time.monotonic()
        if now_s - self._last_s < self.period_s:
            return
        self._last_s = now_s
        f = msg.feedback
        print(f"  line {f.line_number} segment {f.segment_index}: {f.path_length_m * 1e3:.2f}/"
              f"{f.total_length_m * 1e3:.2f} mm at {f.feed_m_s * 6e4:.0f} mm/min (override "
              f"{f.feed_override_ratio:.2f}), contour error {f.contour_error_m * 1e6:.1f} um, "
              f"following error {f.following_error_m * 1e6:.1f} um", flush=True)
