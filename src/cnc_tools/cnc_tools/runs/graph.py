"""Run a scenario through the real node graph: start the node processes, supervise, reap.

Every node is a separate process started from its installed executable (what
``ros2 run`` starts), with a parameters file written for the run, unless the
run composes nodes (``compose="loop"`` or ``"all"``, :mod:`cnc_tools.runs.compose`):
those share one host process and are supervised as members of it. The plant
owns time; the run ends when the plant exits. A node that dies first ends the
run with a :class:`NodeDied` naming it. All processes are stopped and reaped on
every way out: errors, SIGINT/SIGTERM/SIGHUP to the runner, and the runner's own
death (:mod:`cnc_tools.runs.lifetime`). The run folder holds ``pids.json`` (the
runner's and every node's pid) and ``summary.json``, which always ends with how
the run ended.
"""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import CncError, FaultError
from cnc_contour_control.graph.graph_files import write_params_file
from cnc_tools.nodes.host_spec import HOST, MemberExit, exits_path, read_exits
from cnc_tools.runs.compose import ProcessGroup, group_nodes, write_host_spec
from cnc_tools.runs.dds import loopback_env
from cnc_tools.runs.graph_nodes import NAMESPACE, NodeSpec, graph_nodes, recorder_spec, write_params_dir
from cnc_tools.runs.lifetime import (
    RunInterrupted,
    amend_summary,
    check_stop,
    die_with_parent,
    read_summary,
    runner_stop_signals,
    settle_summary,
)
from cnc_tools.runs.managed import managed_nodes
from cnc_tools.runs.namespaces import remap_arguments, run_namespace
from cnc_tools.runs.scenario import Scenario

#: Seconds between two looks at the processes (and at stop signals) while a run waits.
POLL_S = 0.05
#: How long a partner the plant's fault says left the graph may take to end its process after the plant's
#: (it leaves the graph before its interpreter has torn down) [s].
PARTNER_EXIT_GRACE_S = 5.0


class NodeDied(FaultError):
    """A node of the run exited before its time; ``node`` names it."""

    def __init__(self, node: str, message: str) -> None:
        self.node = node
        super().__init__(message)


@dataclass
class RunResult:
    """What a graph run produced."""

    run_dir: Path
    summary: dict[str, Any]
    exit_codes: dict[str, int | None] = field(default_factory=dict)
    bag_path: Path | None = None
    namespace: str = NAMESPACE

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
    """The processes of one run, all in ``namespace``; use as a context manager so they are always reaped.

    ``compose`` (:data:`~cnc_tools.runs.compose.COMPOSE_MODES`) puts nodes into one
    host process; ``processes`` is keyed by process (a node's name, or
    :data:`~cnc_tools.runs.compose.HOST`), exit codes and waits by node.

    Every node runs in its own session (a terminal's Ctrl-C reaches the runner
    only, which stops the nodes in order) and dies with the runner
    (:func:`~cnc_tools.runs.lifetime.die_with_parent`).
    """

    def __init__(self, nodes: Sequence[NodeSpec], run_dir: Path, env: Mapping[str, str] | None = None,
                 namespace: str = NAMESPACE, compose: str = "none") -> None:
        self.nodes = list(nodes)
        self.groups = group_nodes(self.nodes, compose)
        self.process_of = {spec.name: group.name for group in self.groups for spec in group.nodes}
        self.run_dir = run_dir
        self.namespace = namespace
        self.env = dict(env) if env is not None else loopback_env()
        self.processes: dict[str, subprocess.Popen[bytes]] = {}
        self._preexec = die_with_parent()

    def __enter__(self) -> GraphRun:
        self.run_dir.mkdir(parents=True, exist_ok=True)
        try:
            for group in self.groups:
                self.processes[group.name] = self._start(group)
            self._write_pids()
            write_params_dir(self.nodes, self.run_dir, self.namespace, files=False)  # graph.yaml: launchable
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def node_names(self) -> list[str]:
        """Every node of the run, composed or not."""
        return [spec.name for spec in self.nodes]

    def _arguments(self, spec: NodeSpec) -> list[str]:
        """The node's ROS arguments (its own process's, or its constructor's in a host): name, namespace, remaps,
        file."""
        params = write_params_file(self.run_dir, self.namespace, spec.name, spec.parameters)
        return ["--ros-args", "-r", f"__ns:={self.namespace}", "-r", f"__node:={spec.name}",
                *remap_arguments(self.namespace), "--params-file", str(params)]

    def _command(self, group: ProcessGroup) -> list[str]:
        """A lone node's executable with its arguments, or the composed host with its spec file."""
        arguments = {spec.name: self._arguments(spec) for spec in group.nodes}
        if group.name != HOST:
            spec = group.nodes[0]
            return [str(find_executable(spec.package, spec.executable)), *arguments[spec.name]]
        return [str(find_executable("cnc_tools", HOST)), str(write_host_spec(self.run_dir, group, arguments))]

    def _start(self, group: ProcessGroup) -> subprocess.Popen[bytes]:
        command = self._command(group)
        with open(self.run_dir / f"{group.name}.log", "wb") as log:  # the child keeps its own descriptor
            return subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=self.env,
                                    start_new_session=True, preexec_fn=self._preexec)

    def _write_pids(self) -> None:
        """``pids.json``: the runner's pid and every node's, for people and tests watching a run."""
        pids = {"runner": os.getpid(),
                "nodes": {name: self.processes[process].pid for name, process in self.process_of.items()
                          if process in self.processes},
                "processes": {name: p.pid for name, p in self.processes.items()}}
        (self.run_dir / "pids.json").write_text(json.dumps(pids, indent=2))

    def wait(self, main: str = "plant", timeout_s: float = 3600.0, poll: Callable[[], None] | None = None,
             may_finish: Sequence[str] = ()) -> dict[str, int | None]:
        """Wait until ``main`` exits; a node that exits first ends the run with :class:`NodeDied` naming it.

        So does a partner that ``main``'s fault says left the graph and that fails within
        :data:`PARTNER_EXIT_GRACE_S` after ``main`` ended (it leaves the graph before its process ends).
        Nodes in ``may_finish`` (a recorder that is done) may exit first with code 0.
        ``poll`` is called every :data:`POLL_S` (progress, stop signals).
        """
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if poll is not None:
                poll()
            codes = self.exit_codes()
            died = self._died(codes, main, may_finish)
            if codes[main] is not None:
                if codes[main] != 0:  # the plant stopped because a partner died: the partner is the cause
                    died = died or self.failed_within(self._partners_that_left(main), PARTNER_EXIT_GRACE_S)
                    if died is not None:
                        raise died
                    codes = self.exit_codes()  # as they are after the grace
                return codes
            if died is not None:
                raise died
            time.sleep(POLL_S)
        raise FaultError(f"run did not finish within {timeout_s} s")

    def _died(self, codes: Mapping[str, int | None], main: str, may_finish: Sequence[str]) -> NodeDied | None:
        """The first node but ``main`` that has exited, unless it may finish and did so with code 0."""
        for name, code in codes.items():
            if name != main and code is not None and not (name in may_finish and code == 0):
                return self._death(name, code)
        return None

    def _death(self, name: str, code: int) -> NodeDied:
        return NodeDied(name, f"node {name} ({self._where(name)}) exited with code {code} during the run; "
                              f"last output: {self.last_output(name)!r}")

    def _partners_that_left(self, main: str) -> list[str]:
        """The nodes that ``main``'s faults in ``summary.json`` say left the graph
        (``<ns>/<name>, ... left the graph``).

        The partner leaves the graph before its interpreter has torn down, so ``main`` may end first.
        """
        summary = read_summary(self.run_dir / "summary.json") or {}
        lost = " ".join(fault.split(" left the graph", 1)[0] for fault in summary.get("faults", [])
                        if " left the graph" in fault)
        return [name for name in self.node_names if name != main
                and re.search(rf"{re.escape(self.namespace)}/{re.escape(name)}(?![\w/])", lost)]

    def failed_within(self, names: Sequence[str], grace_s: float) -> NodeDied | None:
        """The first of ``names`` whose process ends with a non-zero code within ``grace_s`` (None if none does)."""
        deadline = time.monotonic() + grace_s
        while names:
            codes = self.exit_codes()
            for name in names:
                code = codes[name]
                if code is not None and code != 0:
                    return self._death(name, code)
            if all(codes[name] is not None for name in names) or time.monotonic() > deadline:
                break
            time.sleep(POLL_S)
        return None

    def wait_exit(self, name: str, timeout_s: float, poll: Callable[[], None] | None = None) -> int:
        """Wait for ``name`` to exit by itself; :class:`NodeDied` if it fails, FaultError if it hangs."""
        deadline = time.monotonic() + timeout_s
        while (code := self.exit_codes()[name]) is None:
            if time.monotonic() > deadline:
                raise FaultError(f"node {name} did not finish within {timeout_s} s")
            if poll is not None:
                poll()
            time.sleep(POLL_S)
        if code != 0:
            raise NodeDied(name, f"node {name} ({self._where(name)}) exited with code {code}: "
                                 f"{self.last_output(name)!r}")
        return code

    def exit_codes(self) -> dict[str, int | None]:
        """Exit code of every node (None while running): its process's, or its end noted by its composed host."""
        running = {name: process.poll() for name, process in self.processes.items()}  # before the notes: none missed
        ended = {name: self._member_exits(name) for name in self.processes}
        codes: dict[str, int | None] = {}
        for name, process_name in self.process_of.items():
            noted = ended.get(process_name, {}).get(name)
            codes[name] = noted.code if noted is not None else running.get(process_name)
        return codes

    def _member_exits(self, process_name: str) -> dict[str, MemberExit]:
        """The members a composed host noted as ended (nothing for a lone node's process)."""
        return read_exits(exits_path(self.run_dir, process_name)) if process_name == HOST else {}

    def _where(self, name: str) -> str:
        """``pid N``, or ``in the composed process, pid N`` for a member."""
        process_name = self.process_of[name]
        pid = self.processes[process_name].pid if process_name in self.processes else "?"
        return f"pid {pid}" if process_name == name else f"in the {process_name} process, pid {pid}"

    def last_output(self, name: str) -> str:
        """The last non-empty line a node printed (a composed member: the line its host noted at its end)."""
        ended = self._member_exits(self.process_of.get(name, name)).get(name)
        if ended is not None:
            return ended.message
        path = self.run_dir / f"{self.process_of.get(name, name)}.log"
        text = path.read_text(errors="replace") if path.exists() else ""
        lines = [line for line in text.splitlines() if line.strip()]
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
              timeout_s: float = 3600.0, namespace: str | None = None, compose: str = "none",
              managed: bool = False) -> RunResult:
    """Run ``scenario`` through the node graph in ``run_dir`` (recorded to ``run_dir/bag`` if asked).

    The run's topics live under ``namespace``, by default a fresh ``/cnc/<run id>``
    (:mod:`cnc_tools.runs.namespaces`), so runs in one ROS domain never meet.
    ``compose`` (``none``, ``loop``, ``all``: :mod:`cnc_tools.runs.compose`) puts
    nodes into one process; the bag, summary and verdicts are the same.
    ``managed`` starts the lifecycle nodes unconfigured and a lifecycle
    manager that configures and activates them (:mod:`cnc_tools.runs.managed`).

    Raises
    ------
    NodeDied
        A node exited during the run (``summary.json`` says ``node died``, naming it).
    RunInterrupted
        SIGINT, SIGTERM or SIGHUP reached the runner (``summary.json``: ``interrupted``).
    FaultError
        The run or the recorder did not finish in time.
    """
    run_dir.mkdir(parents=True, exist_ok=True)
    namespace = run_namespace(namespace=namespace)
    extra = [recorder_spec(scenario, run_dir / "bag")] if record else []
    nodes = [*extra, *graph_nodes(scenario, run_dir, extra_subscribers + len(extra),
                                  extra_readers=[spec.name for spec in extra])]
    if managed:
        nodes = managed_nodes(nodes)
    run = GraphRun(nodes, run_dir, env, namespace, compose)
    with runner_stop_signals() as signals:
        try:
            with run:
                summary = _supervise(run, record, timeout_s, _chain(lambda: check_stop(signals, run_dir), on_poll))
        except BaseException as err:
            settle_summary(run_dir / "summary.json", _ended_as(err), str(err), run.exit_codes())
            raise
    summary = amend_summary(run_dir / "summary.json", {"ends_by": scenario.ends_by})
    result = RunResult(run_dir, summary, run.exit_codes(), namespace=namespace)
    if record:
        result.bag_path = run_dir / "bag"
    return result


def _supervise(run: GraphRun, record: bool, timeout_s: float, poll: Callable[[], None]) -> dict[str, Any]:
    """Wait for the plant's end (and the recorder's); the plant's summary of a finished or faulted run."""
    learner = [name for name in run.node_names if name == "compensator"]  # exits once its state is saved
    codes = run.wait("plant", timeout_s, poll, may_finish=["recorder", *learner])
    summary = read_summary(run.run_dir / "summary.json")
    if summary is None or summary.get("status") not in ("finished", "faulted"):
        raise NodeDied("plant", f"node plant exited with code {codes['plant']} before the run ended: "
                                f"{run.last_output('plant')!r}")
    if not summary.get("faults"):
        for name in (*learner, *(["recorder"] if record else [])):
            run.wait_exit(name, 60.0, poll)
    return summary


def _chain(*callbacks: Callable[[], None] | None) -> Callable[[], None]:
    """One callback calling each given one in order."""
    def call() -> None:
        for callback in callbacks:
            if callback is not None:
                callback()

    return call


def _ended_as(err: BaseException) -> str:
    """The summary status of a run that ended with ``err``."""
    if isinstance(err, NodeDied):
        return "node died"
    if isinstance(err, (RunInterrupted, KeyboardInterrupt)):
        return "interrupted"
    return "timed out" if isinstance(err, FaultError) else "interrupted"
