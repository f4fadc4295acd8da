"""Stop signals noted, not acted on, inside a ``with`` block: the nodes' and the runner's one mechanism (ROS-free).

A handler that acts at once stops the process wherever it is: rclpy's own
handlers shut the context down in the middle of a callback (its next publish
raises "publisher's context is invalid"), and a runner's would leave a run
between a fork and the bookkeeping of the child. Noted instead, the signal is
acted on where stopping is safe: a node's spin loop at its next turn
(:func:`cnc_contour_control.nodes.common.spin_node`), the runner's wait loop
at its next poll (:func:`cnc_tools.runs.lifetime.check_stop`). The first signal
counts; later ones while stopping are ignored. Outside the main thread, where
Python cannot install handlers, the block installs nothing.

A node that does not stop can say where it is: :data:`STACK_DUMP_SIGNAL` (SIGUSR1) prints every thread's stack
to its stderr (:func:`faulthandler.register`, installed by :meth:`StopSignals.__enter__` in the main thread and
kept to the process's end, when a stuck exit is what it shows), ``kill -USR1 <pid>``.
"""
from __future__ import annotations

import faulthandler
import signal
import threading
from collections.abc import Sequence
from types import FrameType
from typing import Any, ClassVar

#: What stops a node: Ctrl-C, and the SIGTERM of its runner, of launch or of its dying parent.
NODE_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: What makes a process inside a ``with StopSignals()`` block print every thread's stack to stderr and go on.
STACK_DUMP_SIGNAL = signal.SIGUSR1
#: Where the stacks go: the process's descriptor 2 (``sys.stderr`` may be an object without one, as under capture).
STDERR_FD = 2


class StopSignals:
    """Within ``with``: ``signals`` are noted (:attr:`signum`, :attr:`requested`), then the previous handlers return.

    Parameters
    ----------
    signals : sequence of int
        The signals to note (default :data:`NODE_STOP_SIGNALS`; the runner adds SIGHUP).
    """

    #: The process's innermost installed instance, while its ``with`` block runs.
    active: ClassVar[StopSignals | None] = None

    def __init__(self, signals: Sequence[int] = NODE_STOP_SIGNALS) -> None:
        self.signals = tuple(signals)
        self.signum: int | None = None
        self.installed = threading.current_thread() is threading.main_thread()
        self._previous: dict[int, Any] = {}
        self._outer: StopSignals | None = None

    def __enter__(self) -> StopSignals:
        if self.installed:
            self._previous = {signum: signal.signal(signum, self._note) for signum in self.signals}
            faulthandler.register(STACK_DUMP_SIGNAL, file=STDERR_FD, all_threads=True)
            self._outer, StopSignals.active = StopSignals.active, self
        return self

    def __exit__(self, *exc: object) -> None:
        if StopSignals.active is self:
            StopSignals.active = self._outer
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)

    def _note(self, signum: int, frame: FrameType | None) -> None:
        self.signum = self.signum or signum  # the first one counts; later ones while stopping are ignored

    @property
    def requested(self) -> bool:
        """True once a stop signal came."""
        return self.signum is not None

    @classmethod
    def stopping(cls) -> bool:
        """True once a signal came to the process's active instance (its guarded callbacks then do nothing)."""
        return cls.active is not None and cls.active.requested
