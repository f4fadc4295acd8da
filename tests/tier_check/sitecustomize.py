"""The tier check's note of DDS participants (``CNC_TIER_CHECK=1``, see the root ``conftest.py``).

On ``PYTHONPATH`` while the check is on, so that every Python process of a test session loads it at start-up,
node processes and ``cnc-contour`` calls included. While ``CNC_PARTICIPANT_LOG`` names a file, each
``rclpy`` context initialised (the one way a Python process of this suite starts a DDS participant) appends
the process's id and command line to that file. rclpy itself is not imported here: it is wrapped when some
other import loads it, so a process that never uses ROS stays without it.
"""
from __future__ import annotations

import os
import sys
from importlib.abc import MetaPathFinder
from importlib.machinery import ModuleSpec, PathFinder
from types import ModuleType
from typing import Any

LOG_VARIABLE = "CNC_PARTICIPANT_LOG"


def note_participant() -> None:
    """Append this process to the log file named by ``CNC_PARTICIPANT_LOG`` (nothing when it is unset)."""
    log = os.environ.get(LOG_VARIABLE)
    if log:
        with open(log, "a", encoding="utf-8") as out:
            out.write(f"pid {os.getpid()}: {' '.join(sys.argv)}\n")


def wrap_context(context_module: ModuleType) -> None:
    """Make ``rclpy.context.Context.init`` note the participant before it starts it (once per class)."""
    context = context_module.Context
    if getattr(context.init, "notes_participants", False):
        return
    original = context.init

    def init(self: Any, *args: Any, **kwargs: Any) -> Any:
        note_participant()
        return original(self, *args, **kwargs)

    init.notes_participants = True  # type: ignore[attr-defined]  # a marker on the function object: wrapped once
    context.init = init


class _WrapRclpyContext(MetaPathFinder):
    """Finds ``rclpy.context`` like the path finder does, and wraps its Context once the module has run."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> ModuleSpec | None:
        if name != "rclpy.context":
            return None
        spec = PathFinder.find_spec(name, path)
        if spec is None or spec.loader is None:
            return spec
        run_module = spec.loader.exec_module

        def exec_module(module: ModuleType) -> None:
            run_module(module)
            wrap_context(module)

        spec.loader.exec_module = exec_module  # type: ignore[method-assign]  # this spec's loader only
        return spec


def install() -> None:
    """Wrap rclpy's Context now if it is loaded, else when it is (idempotent)."""
    if "rclpy.context" in sys.modules:
        wrap_context(sys.modules["rclpy.context"])
    elif not any(isinstance(finder, _WrapRclpyContext) for finder in sys.meta_path):
        sys.meta_path.insert(0, _WrapRclpyContext())


install()
