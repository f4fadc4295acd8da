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

from cnc_contour_control.errors import CncError, FaultError
from cnc_tools.runs.dds import loopback_env
from cnc_tools.runs.graph_nodes import NAMESPACE, NodeSpec, graph_nodes, recorder_spec, ros_params_yaml
from cnc_tools.runs.scenario import Scenario


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


