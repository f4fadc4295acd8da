"""Lint and types as tests: ``ruff check .`` (ruff.toml) and ``mypy`` (mypy.ini) from the repo root must pass.

Both run as real subprocesses of this environment's Python, with the same configuration a person runs by
hand (``.venv/bin/ruff check .``, ``.venv/bin/mypy``). mypy keeps its cache in ``.mypy_cache`` (ignored by
git): a fresh clone checks cold, later runs only what changed.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: A cold mypy run of the three packages takes about 20 s of one core; the bound leaves room for a loaded machine.
TIMEOUT_S = 600.0


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=TIMEOUT_S, check=False)


def _report(result: subprocess.CompletedProcess[str]) -> str:
    return f"`{' '.join(result.args[2:])}` exited {result.returncode}:\n{result.stdout}{result.stderr}"


def test_ruff_finds_nothing() -> None:
    result = _run("ruff", "check", ".")
    assert result.returncode == 0, _report(result)


def test_mypy_finds_nothing() -> None:
    assert (ROOT / "mypy.ini").is_file(), "mypy.ini, the configuration this test checks with, is missing"
    result = _run("mypy")
    assert result.returncode == 0, _report(result)
    assert "Success: no issues found" in result.stdout, _report(result)
