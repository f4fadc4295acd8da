"""Where a run's topics live: one ROS namespace per run, so runs in one domain never meet.

Every node of a run is started in the run's namespace (``/cnc/<run id>``
unless the user names one); ``/clock`` and ``/diagnostics``, absolute in the
nodes (as a ROS user expects when starting them by hand or from the launch
file), are remapped into it by the runner. A run's topics, its statuses and
its bag are then its own. See docs/design.md §3 ("Two runs in one domain").
"""
from __future__ import annotations

import re
import secrets

from cnc_contour_control.core import topics as t
from cnc_contour_control.core.errors import ConfigError

#: Topics the nodes publish under absolute names; the runner moves them into the run's namespace.
REMAPPED = (t.CLOCK.name, t.DIAGNOSTICS.name)
_TOKEN = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


def new_run_id() -> str:
    """A fresh run id, a valid ROS name token: ``run_`` and 8 random hex digits."""
    return f"run_{secrets.token_hex(4)}"


def run_namespace(run_id: str | None = None, namespace: str | None = None) -> str:
    """The namespace of a run: ``namespace`` if named (validated), else ``/cnc/<run id>`` (a fresh id if None)."""
    if namespace is None:
        return f"{t.DEFAULT_NAMESPACE}/{run_id or new_run_id()}"
    tokens = namespace.strip("/").split("/")
    if not namespace.startswith("/") or not all(_TOKEN.fullmatch(token) for token in tokens):
        raise ConfigError(f"namespace must be an absolute ROS namespace such as /cnc/bench1 "
                          f"(tokens of letters, digits, '_', not starting with a digit), got {namespace!r}")
    return namespace.rstrip("/")


def remap_arguments(namespace: str) -> list[str]:
    """``--ros-args`` remaps that put the run's absolute topics (``/clock``, ``/diagnostics``) under ``namespace``."""
    arguments: list[str] = []
    for name in REMAPPED:
        arguments += ["-r", f"{name}:={t.qualify(namespace, name.lstrip('/'))}"]
    return arguments
