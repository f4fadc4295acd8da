"""The subcommands of ``cnc-contour``, listed explicitly (one module per subcommand, imported when used)."""
from __future__ import annotations

from cnc_tools.cli.common import Subcommand


def _command(name: str, configure: str, handler: str, help_text: str) -> Subcommand:
    return Subcommand(f"cnc_tools.cli.{name}", configure, handler, help_text)


#: Subcommands by name, in the order ``--help`` lists them.
COMMANDS: dict[str, Subcommand] = {
    "run": _command("run", "configure", "run",
                    "run a scenario through the node graph (or the engine), record, score, plot"),
    "check": _command("check", "configure", "check", "validate a scenario and print what it resolves to"),
    "params": _command("params", "configure", "params", "write a scenario's node parameter files (for ros2 launch)"),
    "config-files": _command("config_files", "configure", "config_files",
                             "write (--check: check) the parameter files the packages install"),
    "score": _command("score", "configure_score", "score", "score recorded runs (exact contour error)"),
    "report": _command("score", "configure_report", "report", "PNG plots of recorded runs, side by side"),
    "circular": _command("circular", "configure", "circular",
                         "ballbar diagnoses of a recorded circle (a cw and a ccw run)"),
    "replay": _command("replay", "configure", "replay", "republish a bag with its recorded timing"),
    "send-program": _command("send_program", "configure", "send_program",
                             "run a part program on a running interpolator (RunProgram action; Ctrl-C cancels)"),
    "ros": _command("ros", "configure", "ros",
                    "nodes, topics, echo, hz, param, action send: ROS tools for a wheel install (no ros2 CLI)"),
    "machine": _command("machine", "configure", "machine",
                        "e-stop, release, reset, enable or disable a running graph's plant and servos"),
    "identify-friction": _command("identify_friction", "configure", "identify_friction",
                                  "identify an axis's friction-velocity curve (paper 000)"),
    "bench": _command("bench", "configure", "bench", "speed benchmarks and paper reproductions"),
    "tune": _command("tune", "configure", "tune", "tune scenario parameters by differential evolution (paper 003)"),
}
