"""Processes a bench starts: started with the loopback DDS environment, always stopped by pid and reaped.

:func:`round_trips` runs the two :mod:`cnc_tools.bench.pingpong` peers and
returns the measured round-trip times.
"""
from __future__ import annotations

import json
import os
import secrets
import signal
import subprocess
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import FaultError
from cnc_tools.runs.dds import loopback_env


class Peers:
    """Python module processes of one measurement; a context manager that stops every one it started."""

    def __init__(self, run_dir: Path, env: Mapping[str, str] | None = None) -> None:
        self.run_dir = run_dir
        self.env = dict(env) if env is not None else loopback_env()
        self.processes: dict[str, subprocess.Popen[bytes]] = {}

    def __enter__(self) -> Peers:
        self.run_dir.mkdir(parents=True, exist_ok=True)
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def start(self, name: str, module: str, args: Sequence[str]) -> subprocess.Popen[bytes]:
        """Start ``python -m module args`` as ``name``; its output goes to ``<run_dir>/<name>.log``."""
        with open(self.run_dir / f"{name}.log", "wb") as log:
            process = subprocess.Popen([sys.executable, "-m", module, *args], stdout=log,
                                       stderr=subprocess.STDOUT, env=self.env, start_new_session=True)
        self.processes[name] = process
        return process

    def wait(self, name: str, timeout_s: float) -> int:
        """Wait for ``name`` to exit; a FaultError if it does not within ``timeout_s``."""
        try:
            return self.processes[name].wait(timeout=timeout_s)
        except subprocess.TimeoutExpired as err:
            raise FaultError(f"{name} (pid {self.processes[name].pid}) did not finish within {timeout_s} s") from err

    def stop(self, grace_s: float = 5.0) -> None:
        """SIGINT, then SIGTERM, then SIGKILL each process still running (by its pid); reap them all."""
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            alive = [p for p in self.processes.values() if p.poll() is None]
            for process in alive:
                process.send_signal(sig)
            for process in alive:
                try:
                    process.wait(timeout=grace_s)
                except subprocess.TimeoutExpired:
                    pass
        for process in self.processes.values():
            process.wait()

    def last_output(self, name: str) -> str:
        """The last non-empty line ``name`` printed."""
        path = self.run_dir / f"{name}.log"
        text = path.read_text(errors="replace") if path.exists() else ""
        lines = [line for line in text.splitlines() if line.strip()]
        return lines[-1] if lines else ""


def run_role(node_name: str, body: Callable[[Any, Any], int], namespace: str = "") -> int:
    """A peer process's side: ``body(node, executor)`` on a fresh rclpy node with the nodes' executor;
    its exit code (0 when interrupted), the node destroyed and rclpy shut down on every way out."""
    import rclpy
    from rclpy.executors import ExternalShutdownException

    from cnc_contour_control.nodes.common import make_executor

    rclpy.init(args=None)
    node = rclpy.create_node(node_name, namespace=namespace)
    executor = make_executor(node.context)
    executor.add_node(node)
    try:
        return body(node, executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


PINGPONG = "cnc_tools.bench.pingpong"


def round_trips(run_dir: Path, message: str, iterations: int, warmup: int, timeout_s: float = 120.0) -> list[float]:
    """Round-trip times [s] of ``iterations`` pings between two fresh processes (loopback DDS).

    Raises
    ------
    FaultError
        If the pinger fails or does not finish within ``timeout_s``.
    """
    token = f"bench_{os.getpid()}_{secrets.token_hex(4)}"
    topics = ["--ping", f"/{token}/ping", "--pong", f"/{token}/pong", "--message", message]
    out = run_dir / f"pingpong_{message}.json"
    with Peers(run_dir) as peers:
        peers.start(f"echo_{message}", PINGPONG, ["echo", *topics])
        peers.start(f"ping_{message}", PINGPONG, ["ping", *topics, "--iterations", str(iterations),
                                                  "--warmup", str(warmup), "--out", str(out)])
        code = peers.wait(f"ping_{message}", timeout_s)
        if code != 0 or not out.exists():
            raise FaultError(f"ping-pong ({message}) failed with exit code {code}: "
                             f"{peers.last_output(f'ping_{message}')!r}")
    return list(json.loads(out.read_text())["round_trip_s"])
