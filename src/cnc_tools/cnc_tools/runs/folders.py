"""Where runs write: the project root and sortable run-folder names."""
from __future__ import annotations

import os
from datetime import UTC, datetime
from pathlib import Path


def project_root() -> Path:
    """The checkout (CNC_CONTOUR_ROOT, set by ./dev) or the current directory."""
    return Path(os.environ.get("CNC_CONTOUR_ROOT", Path.cwd()))


def timestamp() -> str:
    """A sortable UTC timestamp for run folders."""
    return datetime.now(UTC).strftime("%Y%m%dT%H%M%S_%fZ")
