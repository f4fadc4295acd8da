"""Run a scenario through the real node graph: start the node processes, supervise, reap.

Every node is a separate process started from its installed executable (what
``ros2 run`` starts), with a parameters file written for the run. The plant
owns time; the run ends when the plant exits. A node that dies first ends the
run with an error naming it. All processes are stopped and reaped, also on
errors and interrupts.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from cnc_contour_control.errors import CncError, FaultError
from cnc_tools.runs.dds import loopback_env
from cnc_tools.runs.scenario import Scenario

NAMESPACE = "/cnc"


@dataclass(frozen=True)
class NodeSpec:
    """One process of the graph: package, executable, node name, parameters."""

    package: str
    executable: str
    name: str
    parameters: Mapping[str, Any]


@dataclass
class RunResult:
    """What a graph run produced."""

    run_dir: Path
    summary: dict[str, Any]
    exit_codes: dict[str, int | None] = field(default_factory=dict)
    bag_path: Path | None = None

    @property
    def faults(self) -> list[str]:
        """Faults reported by the plant."""
        return list(self.summary.get("faults", []))


def find_executable(package: str, executable: str) -> Path:
    """``<prefix>/lib/<package>/<executable>`` from AMENT_PREFIX_PATH, as ``ros2 run`` finds it."""
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        candidate = Path(prefix) / "lib" / package / executable
        if prefix and candidate.is_file():
            return candidate
    raise CncError(f"executable {package}/{executable} not found under AMENT_PREFIX_PATH; run ./dev setup")


def graph_nodes(scenario: Scenario, run_dir: Path, extra_subscribers: int = 0,
                input_timeout_s: float = 5.0) -> list[NodeSpec]:
    """The node processes of a scenario (plant, interpolator, one servo per axis).

    ``extra_subscribers`` readers (a recorder, a test probe) subscribe to every
    lockstep topic besides the graph's own; each stage waits for all its readers
    before it publishes its first message, so nothing is lost at start-up.
    """
    axes = list(scenario.axes)
    program_file = run_dir / "program.yaml"
    program_file.write_text(yaml.safe_dump({"program": _with_axes(scenario)}))
    servos = [_servo_spec(scenario, config, input_timeout_s, 1 + extra_subscribers) for config in scenario.servos]
    limits = scenario.limits
    interpolator = NodeSpec("cnc_contour_control", "interpolator", "interpolator", {
        "axes": axes, "program_file": str(program_file),
        "max_velocity_mm_min": [v * 60e3 for v in limits.max_velocity_m_s],
        "max_acceleration_mm_s2": [a * 1e3 for a in limits.max_acceleration_m_s2],
        "corner_angle_tolerance_deg": float(scenario.interpolator.corner_angle_tolerance_deg),
        "arc_centripetal_fraction": float(scenario.interpolator.arc_centripetal_fraction),
        "clamp_feed": scenario.interpolator.clamp_feed, "min_subscribers": len(servos) + extra_subscribers,
    })
    plant = _plant_spec(scenario, run_dir, 1 + len(servos) + extra_subscribers, input_timeout_s)
    return [plant, interpolator, *servos]


def _with_axes(scenario: Scenario) -> dict[str, Any]:
    program = {"name": scenario.name, **dict(scenario.raw["program"])}
    if "gcode_file" in program and scenario.source is not None:
        program["gcode_file"] = str((scenario.source.parent / program["gcode_file"]).resolve())
    return program


def _plant_spec(scenario: Scenario, run_dir: Path, subscribers: int, timeout_s: float) -> NodeSpec:
    plant = scenario.plant
    return NodeSpec("cnc_plant_sim", "plant", "plant", {
        "model": plant.model, "axes": list(plant.axes), "seed": int(plant.seed), "substeps": int(plant.substeps),
        "gain_variation_pct": float(plant.variation.gain_pct),
        "time_constant_variation_pct": float(plant.variation.time_constant_pct),
        "friction_variation_pct": float(plant.variation.friction_pct),
        "axis_overrides": yaml.safe_dump(dict(plant.axis_overrides)),
        "initial_position_m": [float(v) for v in scenario.program.start_m],
        "sample_time_s": float(scenario.sample_time_s), "duration_s": float(scenario.duration_s),
        "mode": scenario.mode, "expected_subscribers": subscribers,
        # Thrice the stages' timeout: the stage nearest the missing input reports it first.
        "summary_file": str(run_dir / "summary.json"), "command_timeout_s": 3.0 * float(timeout_s),
    })


def _servo_spec(scenario: Scenario, config: Any, timeout_s: float, readers: int) -> NodeSpec:
    return NodeSpec("cnc_contour_control", "servo", f"servo_{config.axis_name}", {
        "axis": config.axis_name, "sample_time_s": float(scenario.sample_time_s),
        "law": config.law, "law_params": yaml.safe_dump(dict(config.law_params), default_flow_style=True).strip(),
        "counts_per_m": float(config.counts_per_m), "ff1": float(config.ff1), "ff2": float(config.ff2),
        "output_limit": float(config.output_limit), "quantum": float(config.quantum), "command_unit": config.command_unit,
        "input_timeout_s": float(timeout_s), "min_subscribers": readers,
    })


class GraphRun:
    """The processes of one run; use as a context manager so they are always reaped."""

    def __init__(self, nodes: Sequence[NodeSpec], run_dir: Path, env: Mapping[str, str] | None = None) -> None:
        self.nodes = list(nodes)
        self.run_dir = run_dir
        self.env = dict(env) if env is not None else loopback_env()
        self.processes: dict[str, subprocess.Popen[bytes]] = {}

    def __enter__(self) -> GraphRun:
        self.run_dir.mkdir(parents=True, exist_ok=True)
        for spec in self.nodes:
            self.processes[spec.name] = self._start(spec)
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _start(self, spec: NodeSpec) -> subprocess.Popen[bytes]:
        params = self.run_dir / f"{spec.name}.params.yaml"
        params.write_text(ros_params_yaml(f"{NAMESPACE}/{spec.name}", spec.parameters))
        command = [str(find_executable(spec.package, spec.executable)), "--ros-args",
                   "-r", f"__ns:={NAMESPACE}", "-r", f"__node:={spec.name}", "--params-file", str(params)]
        log = open(self.run_dir / f"{spec.name}.log", "wb")  # noqa: SIM115 (closed with the process)
        return subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=self.env, start_new_session=True)

    def wait(self, main: str = "plant", timeout_s: float = 3600.0, poll: Callable[[], None] | None = None,
             may_finish: Sequence[str] = ()) -> dict[str, int | None]:
        """Wait until ``main`` exits; a node that exits first ends the run with a FaultError naming it.

        Nodes in ``may_finish`` (a recorder that is done) may exit first with code 0.
        """
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if poll is not None:
                poll()
            if self.processes[main].poll() is not None:
                return self.exit_codes()
            for name, process in self.processes.items():
                if name != main and process.poll() is not None and not (name in may_finish and process.returncode == 0):
                    raise FaultError(f"node {name} (pid {process.pid}) exited with code {process.returncode} "
                                     f"during the run; last output: {self.last_output(name)!r}")
            time.sleep(0.05)
        raise FaultError(f"run did not finish within {timeout_s} s")

    def wait_exit(self, name: str, timeout_s: float) -> int:
        """Wait for ``name`` to exit by itself; FaultError naming it if it fails or hangs."""
        try:
            code = self.processes[name].wait(timeout=timeout_s)
        except subprocess.TimeoutExpired as err:
            raise FaultError(f"node {name} did not finish within {timeout_s} s") from err
        if code != 0:
            raise FaultError(f"node {name} exited with code {code}: {self.last_output(name)!r}")
        return code

    def exit_codes(self) -> dict[str, int | None]:
        """Exit code of every process (None while running)."""
        return {name: process.poll() for name, process in self.processes.items()}

    def last_output(self, name: str) -> str:
        """The last non-empty line a node printed."""
        path = self.run_dir / f"{name}.log"
        lines = [line for line in path.read_text(errors="replace").splitlines() if line.strip()] if path.exists() else []
        return lines[-1] if lines else ""

    def stop(self, grace_s: float = 5.0) -> None:
        """SIGINT every process, then SIGTERM, then SIGKILL; reap them all."""
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            alive = [p for p in self.processes.values() if p.poll() is None]
            for process in alive:
                process.send_signal(sig)
            deadline = time.monotonic() + grace_s
            for process in alive:
                try:
                    process.wait(timeout=max(0.0, deadline - time.monotonic()))
                except subprocess.TimeoutExpired:
                    pass
        for process in self.processes.values():
            process.wait()


def recorder_spec(scenario: Scenario, bag_path: Path) -> NodeSpec:
    """The recorder of a run: every topic of the graph, into ``bag_path``."""
    return NodeSpec("cnc_tools", "recorder", "recorder", {"output": str(bag_path), "axes": list(scenario.axes)})


def run_graph(scenario: Scenario, run_dir: Path, record: bool = False, extra_subscribers: int = 0,
              env: Mapping[str, str] | None = None, on_poll: Callable[[], None] | None = None,
              timeout_s: float = 3600.0) -> RunResult:
    """Run ``scenario`` through the node graph in ``run_dir`` (recorded to ``run_dir/bag`` if asked)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    extra = [recorder_spec(scenario, run_dir / "bag")] if record else []
    nodes = [*extra, *graph_nodes(scenario, run_dir, extra_subscribers + len(extra))]
    with GraphRun(nodes, run_dir, env) as run:
        codes = run.wait("plant", timeout_s, on_poll, may_finish=["recorder"])
        summary = _read_summary(run_dir)
        if summary is None:
            raise FaultError(f"node plant exited with code {codes['plant']} before the run ended: "
                             f"{run.last_output('plant')!r}")
        if record and not summary.get("faults"):
            run.wait_exit("recorder", 60.0)
        codes = run.exit_codes()
    result = RunResult(run_dir, summary, codes)
    if record:
        result.bag_path = run_dir / "bag"
    return result


def _read_summary(run_dir: Path) -> dict[str, Any] | None:
    """The plant's final summary; None if it never wrote one or stopped while running."""
    path = run_dir / "summary.json"
    summary = json.loads(path.read_text()) if path.exists() else None
    return summary if summary and summary.get("status") in ("finished", "faulted") else None


class _QuotedDumper(yaml.SafeDumper):
    """Quotes every string, so rcl's YAML 1.1 parser never reads 'y' or 'no' as a bool."""


_QuotedDumper.add_representer(str, lambda dumper, value: dumper.represent_scalar("tag:yaml.org,2002:str", value, style='"'))


def ros_params_yaml(node: str, parameters: Mapping[str, Any]) -> str:
    """A ROS 2 parameters file for one node."""
    return yaml.dump({node: {"ros__parameters": dict(parameters)}}, Dumper=_QuotedDumper)
