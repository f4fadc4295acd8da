"""``cnc-contour send-program FILE``: run a part program on a running interpolator (RunProgram action).

A G-code file is sent as text (the interpolator may run on another host); any
other file as its absolute path (a YAML program, read by the interpolator).
A G-code file may carry comments in an 8-bit code page (read as the
interpolator reads it, :mod:`cnc_contour_control.motion.gcode_file`); a binary
or unreadable file is one error line, exit 2. Feedback is printed as it comes;
Ctrl-C cancels the goal (a controlled stop on the path), waits for its result
(a second Ctrl-C stops waiting), prints one line and exits 130. Exit code
otherwise: 0 completed, 1 rejected or cancelled, 3 faulted, aborted or unknown.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.motion.gcode_file import not_a_file, read_gcode_file
from cnc_contour_control.motion.program_file import GCODE_SUFFIXES

#: Result outcome name (RunProgram.Result constants, lower case) -> exit code; any other outcome exits 3.
EXIT_CODES = {"completed": 0, "canceled": 1, "rejected": 1}
#: Exit code of an outcome not in EXIT_CODES (faulted, aborted, unknown).
EXIT_OTHER = 3
#: Exit code after Ctrl-C (128 + SIGINT).
EXIT_INTERRUPTED = 130
#: Wall time to wait for a cancelled goal's result after Ctrl-C, s.
CANCEL_WAIT_S = 30.0


def outcome_name(code: int) -> str:
    """The name of a RunProgram result's ``outcome`` code (``unknown`` for one the action does not define)."""
    from cnc_contour_interfaces.action import RunProgram

    names = {getattr(RunProgram.Result, n): n.lower() for n in dir(RunProgram.Result) if n.isupper()
             and isinstance(getattr(RunProgram.Result, n), int)}
    return names.get(int(code), "unknown")


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
    reason = not_a_file(file, "program")
    if reason is not None:
        raise ConfigError(reason)
    goal = RunProgram.Goal(program_name=file.stem, feed_mm_min=float(args.feed_mm_min),
                           path_tolerance_mm=float(args.path_tolerance_mm))
    if file.suffix.lower() in GCODE_SUFFIXES:
        goal.gcode = read_gcode_file(file, "program", ConfigError)
    else:
        goal.program_file = str(file.resolve())
    return goal


def send_program(args: argparse.Namespace) -> int:
    """Send the goal, print feedback and the result; the exit code of the outcome."""
    import rclpy
    from rclpy.action import ActionClient
    from rclpy.signals import SignalHandlerOptions

    from cnc_contour_interfaces.action import RunProgram

    goal = goal_of(args)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)  # Ctrl-C: a KeyboardInterrupt here, not a shutdown
    node = rclpy.create_node("send_program")
    client = ActionClient(node, RunProgram, args.action)
    try:
        if not client.wait_for_server(timeout_sec=args.wait_s):
            raise ConfigError(f"no RunProgram server on {args.action} within --wait-s {args.wait_s} s "
                              f"(is the interpolator running with program_source: action, in this ROS domain?)")
        return _run(node, client, goal, args)
    finally:
        client.destroy()  # the node is not destroyed while its action client holds it (destroy_node leaves waitables)
        node.destroy_node()
        rclpy.try_shutdown()


def _run(node: Any, client: Any, goal: Any, args: argparse.Namespace) -> int:
    handle = _wait(node, client.send_goal_async(goal, feedback_callback=FeedbackPrinter()), args.wait_s)
    if handle is None:  # a server found but deaf to this client (its reader not matched yet): never wait for ever
        raise FaultError(f"the RunProgram server on {args.action} did not answer the goal within --wait-s "
                         f"{args.wait_s} s")
    if not handle.accepted:
        print("goal rejected (the interpolator's log and /diagnostics give the reason)", flush=True)
        return 1
    result_future = handle.get_result_async()
    try:
        result = _wait(node, result_future).result
    except KeyboardInterrupt:
        return _cancel(node, handle, result_future)
    _print_result(result)
    return EXIT_CODES.get(outcome_name(result.outcome), EXIT_OTHER)


def _cancel(node: Any, handle: Any, result_future: Any) -> int:
    """Ctrl-C: cancel the goal, wait up to CANCEL_WAIT_S for its result (a second Ctrl-C stops waiting), one line."""
    handle.cancel_goal_async()
    try:
        _wait(node, result_future, CANCEL_WAIT_S)
    except KeyboardInterrupt:
        pass
    if result_future.done():
        result = result_future.result().result
        done = (f"{result.program_name}: {outcome_name(result.outcome)} at {result.path_length_m * 1e3:.3f} of "
                f"{result.total_length_m * 1e3:.3f} mm: {result.reason}")
    else:
        done = "the goal's result did not come (cancel requested)"
    print(f"interrupted: {done}", flush=True)
    return EXIT_INTERRUPTED


def _print_result(result: Any) -> None:
    print(f"{result.program_name}: {outcome_name(result.outcome)}: {result.reason}\n"
          f"  max contour error {result.max_contour_error_m * 1e6:.2f} um, "
          f"rms {result.rms_contour_error_m * 1e6:.2f} um,"
          f" max following error {result.max_following_error_m * 1e6:.2f} um\n"
          f"  cycle time {result.cycle_time_s:.3f} s, path {result.path_length_m * 1e3:.3f} of "
          f"{result.total_length_m * 1e3:.3f} mm, {result.ticks} ticks" + (f", bag {result.bag_path}"
                                                                             if result.bag_path else ""), flush=True)


def _wait(node: Any, future: Any, timeout_s: float = float("inf")) -> Any:
    """Spin ``node`` until ``future`` is done (or ``timeout_s`` of wall time passed: None) and return its result."""
    import rclpy

    deadline_s = time.monotonic() + timeout_s
    while not future.done() and rclpy.ok() and time.monotonic() < deadline_s:
        rclpy.spin_once(node, timeout_sec=0.1)
    return future.result() if future.done() else None


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
