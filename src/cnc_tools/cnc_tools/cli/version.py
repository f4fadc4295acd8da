"""``cnc-contour --version``: the suite's version from the installed package metadata, and the git commit
when the code runs from a checkout (looked up only when asked: one ``git rev-parse``, 2 s at most)."""
from __future__ import annotations

import argparse
import subprocess
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

#: The distribution whose version is the suite's (every package of the suite carries the same one).
DISTRIBUTION = "cnc_tools"
#: How long ``git rev-parse`` may take before the commit is left out [s].
GIT_TIMEOUT_S = 2.0


def package_version() -> str:
    """The installed ``cnc_tools`` version, or ``unknown`` when no metadata is installed."""
    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return "unknown"


def checkout_commit(start: Path | None = None) -> str | None:
    """The short commit of the git checkout holding ``start`` (default: this module's real file), or None."""
    here = (start or Path(__file__)).resolve()
    root = next((p for p in here.parents if (p / ".git").exists()), None)
    if root is None:
        return None
    try:
        found = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"], capture_output=True,
                               text=True, timeout=GIT_TIMEOUT_S, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return found.stdout.strip() or None


def suite_version() -> str:
    """``cnc-contour 0.1.0`` and, from a checkout, ``(git 1a2b3c4d5e6f)``."""
    commit = checkout_commit()
    return f"cnc-contour {package_version()}" + (f" (git {commit})" if commit else "")


class VersionAction(argparse.Action):
    """``--version``: print :func:`suite_version` to stdout and exit 0 (computed only when the option is given)."""

    def __init__(self, option_strings: Sequence[str], dest: str = argparse.SUPPRESS, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        print(suite_version())
        parser.exit(0)
