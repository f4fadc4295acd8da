"""Composed host: several of the suite's nodes in one process, spun by one executor (``composed SPEC``).

The ROS 2 component pattern in Python: the host reads its spec
(:func:`cnc_tools.runs.compose.read_host_spec`), builds each member from its
class (:mod:`cnc_tools.nodes.composable`) with the ROS arguments its own process
would get (``__ns``, ``__node``, the run's remaps, ``--params-file``) and spins
them all on one executor (:func:`~cnc_contour_control.nodes.common.make_executor`).

Messages between members go through a process-local bus
(:mod:`cnc_contour_control.nodes.local_bus`; ``CNC_LOCAL_BUS=0`` turns it off):
the spin loop drains its queue in batches between the executor's turns (timers,
DDS events) and, every :data:`OUTSIDE_POLL_S`, connects members to publishers
outside the process.

Each member ends as its process would: finished (exit code 0), faulted
(:data:`~cnc_contour_control.nodes.common.EXIT_FAULT`) or raised (1, the
exception named by the node whose callback raised it); the host then removes
it from the executor, flushes and destroys it, and notes its end in the exits
file, which the runner reads as it reads a process's exit. The host ends once
every member ended, or on SIGINT/SIGTERM (every member destroyed: the recorder
closes its bag, the plant writes its summary).
"""
from __future__ import annotations

import os
import sys
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.core.stop_signals import StopSignals
from cnc_contour_control.nodes import local_bus
from cnc_contour_control.nodes.common import (
    EXIT_FAULT,
    SuiteNode,
    flush_and_destroy,
    init_ros,
    make_executor,
    wall_time_s,
)
from cnc_tools.nodes.composable import node_class
from cnc_tools.nodes.host_spec import HOST, MemberExit, read_host_spec, write_exits

#: Exit code of a member whose callback raised an error that is not the suite's (Python's own for a traceback).
EXIT_RAISED = 1
#: Wall seconds between two looks at the graph for publishers outside the process (``LocalBus.connect_outside``).
OUTSIDE_POLL_S = 0.25


def make_bus() -> local_bus.LocalBus | None:
    """The host's local bus, unless ``CNC_LOCAL_BUS=0`` (every message over DDS, as before the bus)."""
    return None if os.environ.get("CNC_LOCAL_BUS", "1") == "0" else local_bus.LocalBus()


def culprit(trace: TracebackType | None, nodes: dict[str, Any]) -> str | None:
    """The member whose code raised: the outermost frame of the traceback whose ``self`` is a member node."""
    while trace is not None:
        owner = trace.tb_frame.f_locals.get("self")
        found = next((name for name, node in nodes.items() if owner is node), None)
        if found is not None:
            return found
        trace = trace.tb_next
    return None


class ComposedHost:
    """Members by name, one executor, and the ends noted in ``exits_file``."""

    def __init__(self, context: Any, exits_file: Path | None, stop: StopSignals | None = None) -> None:
        self.context, self.exits_file = context, exits_file
        self.stop = stop  # SIGINT/SIGTERM noted by run_host: the spin loop ends at its next turn
        self.executor = make_executor(context)
        self.bus = make_bus()
        if self.bus is not None:
            local_bus.attach(context, self.bus)
        self.live: dict[str, SuiteNode] = {}
        self.ended: dict[str, SuiteNode] = {}  # members removed: the events executor may still run one queued callback
        self.exits: dict[str, MemberExit] = {}

    def add(self, name: str, cls: type[SuiteNode], arguments: Sequence[str]) -> None:
        """Build one member with its own ROS arguments; a failure is that member's end, not the host's."""
        try:
            node = cls(context=self.context, cli_args=list(arguments),  # type: ignore[call-arg]  # members name themselves
                       use_global_arguments=False)
        except CncError as err:
            self._note(name, EXIT_FAULT, f"FAULT: {err}")
            return
        except Exception as err:
            self._note(name, EXIT_RAISED, f"{type(err).__name__}: {err}", err)
            return
        self.live[name] = node
        self.executor.add_node(node)

    def spin(self, until: Callable[[], bool] | None = None) -> None:
        """Spin until every member ended, a signal came, the context is shut down or ``until()`` holds."""
        next_poll_s = 0.0
        while self.live and self.context.ok() and not self.stopped and not (until is not None and until()):
            try:
                next_poll_s = self._bus_turn(next_poll_s)
                self.executor.spin_once(timeout_sec=0.0 if self.bus is not None and self.bus.pending else 0.1)
            except (KeyboardInterrupt, ExternalShutdownException):
                return
            except Exception as err:
                self._raised(err)
            for name in [n for n, node in self.live.items() if node.finished]:
                node = self.live[name]
                self.end(name, EXIT_FAULT if node.fault_message else 0,
                         f"FAULT: {node.fault_message}" if node.fault_message else "finished")

    @property
    def stopped(self) -> bool:
        """True once SIGINT or SIGTERM came."""
        return self.stop is not None and self.stop.requested

    def _bus_turn(self, next_poll_s: float) -> float:
        """One batch of local deliveries, and the look for outside publishers when due; the next look's time."""
        if self.bus is None:
            return next_poll_s
        self.bus.drain()
        if wall_time_s() < next_poll_s:
            return next_poll_s
        self.bus.connect_outside()
        return wall_time_s() + OUTSIDE_POLL_S

    def _raised(self, err: Exception) -> None:
        """End the member whose callback raised ``err`` (a suite error: a fault); an unknown origin ends the host."""
        name = culprit(err.__traceback__, dict(self.live))
        if name is None and culprit(err.__traceback__, self.ended) is not None:
            return  # a callback of a member that already ended (its end is noted): nothing more to do
        if name is None:
            raise err
        if isinstance(err, CncError):
            self.end(name, EXIT_FAULT, f"FAULT: {err}")
        else:
            self.end(name, EXIT_RAISED, f"{type(err).__name__}: {err}", err)

    def end(self, name: str, code: int, message: str, err: BaseException | None = None) -> None:
        """Remove, flush and destroy one member, and note its end."""
        node = self.live.pop(name)
        self.ended[name] = node
        self.executor.remove_node(node)
        if self.bus is not None:
            self.bus.forget(node)
        try:
            flush_and_destroy(node)
        finally:
            self._note(name, code, message, err)

    def _note(self, name: str, code: int, message: str, err: BaseException | None = None) -> None:
        if err is not None:
            traceback.print_exception(err, file=sys.stderr)
        print(f"[{name}] ended with code {code}: {message}", file=sys.stderr, flush=True)
        self.exits[name] = MemberExit(code, message)
        if self.exits_file is not None:
            write_exits(self.exits_file, self.exits)

    def close(self) -> None:
        """Destroy every member still live (after a signal: no flush; the plant notes ``interrupted``)."""
        for name, node in list(self.live.items()):
            del self.live[name]
            if self.bus is not None:
                self.bus.forget(node)
            flush_and_destroy(node, flush=not self.stopped)
        self.executor.shutdown()
        if self.bus is not None:
            local_bus.detach(self.context)
            print(f"[{HOST}] local bus: {self.bus.delivered} deliveries in process; topics connected to outside "
                  f"publishers: {sorted(set(self.bus.connected)) or 'none'}", file=sys.stderr, flush=True)


def run_host(spec_file: Path, args: Sequence[str] | None = None) -> int:
    """Build the spec's members, spin them until they end; the host's exit code (0 unless the host itself failed)."""
    spec = read_host_spec(spec_file)
    host: ComposedHost | None = None
    with StopSignals() as stop:  # SIGINT/SIGTERM: members destroyed in a live context, no traceback, exit code 0
        init_ros(stop, args)
        try:
            host = ComposedHost(rclpy.get_default_context(),
                                Path(spec["exits_file"]) if spec.get("exits_file") else None, stop)
            for entry in spec["nodes"]:
                host.add(entry["name"], node_class(entry["package"], entry["executable"]), entry["arguments"])
            _spin_profiled(host) if os.environ.get("CNC_PROFILE_OUT") else host.spin()
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            if host is not None:
                host.close()
            rclpy.try_shutdown()
    return 0


def _spin_profiled(host: ComposedHost) -> None:
    """Spin under cProfile (wall clock) and write the statistics to ``$CNC_PROFILE_OUT`` (a developer's aid)."""
    import cProfile
    profile = cProfile.Profile()
    try:
        profile.runcall(host.spin)
    finally:
        profile.dump_stats(os.environ["CNC_PROFILE_OUT"])


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_tools composed SPEC_FILE`` (written by the runner for ``--compose loop|all``)."""
    argv = list(sys.argv if args is None else args)
    plain = rclpy.utilities.remove_ros_args(argv)
    if len(plain) != 2:
        print(f"usage: composed SPEC_FILE (a <process>.compose.yaml the runner wrote), got {plain[1:]}",
              file=sys.stderr)
        raise SystemExit(2)
    raise SystemExit(run_host(Path(plain[1]), argv))
