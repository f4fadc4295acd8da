"""The subcommands of ``cnc-contour``, listed explicitly (one module per subcommand)."""
from __future__ import annotations

from cnc_tools.cli import bench, check, circular, identify_friction, params, replay, run, score, tune
from cnc_tools.cli import config_files
from cnc_tools.cli import send_program
from cnc_tools.cli import machine
from cnc_tools.cli.common import Subcommand

#: Subcommands by name, in the order ``--help`` lists them.
COMMANDS: dict[str, Subcommand] = {
    "run": Subcommand(run.configure, run.run, "run a scenario through the node graph (or the engine), record, score, plot"),
    "check": Subcommand(check.configure, check.check, "validate a scenario and print what it resolves to"),
    "params": Subcommand(params.configure, params.params, "write a scenario's node parameter files (for ros2 launch)"),
    "config-files": Subcommand(config_files.configure, config_files.config_files,
                               "write (--check: check) the parameter files the packages install"),
    "score": Subcommand(score.configure_score, score.score, "score recorded runs (exact contour error)"),
    "report": Subcommand(score.configure_report, score.report, "PNG plots of recorded runs, side by side"),
    "circular": Subcommand(circular.configure, circular.circular,
                           "ballbar diagnoses of a recorded circle (a cw and a ccw run)"),
    "replay": Subcommand(replay.configure, replay.replay, "republish a bag with its recorded timing"),
    "send-program": Subcommand(send_program.configure, send_program.send_program,
                               "run a part program on a running interpolator (RunProgram action; Ctrl-C cancels)"),
    "machine": Subcommand(machine.configure, machine.machine,
                          "e-stop, release, reset, enable or disable a running graph's plant and servos"),
    "identify-friction": Subcommand(identify_friction.configure, identify_friction.identify_friction,
                                    "identify an axis's friction-velocity curve (paper 000)"),
    "bench": Subcommand(bench.configure, bench.bench, "speed benchmarks and paper reproductions"),
    "tune": Subcommand(tune.configure, tune.tune, "tune scenario parameters by differential evolution (paper 003)"),
}
