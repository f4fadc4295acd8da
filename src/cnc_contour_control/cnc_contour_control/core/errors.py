"""The project's error hierarchy (one for every package of the suite)."""
from __future__ import annotations


class CncError(Exception):
    """Base of every error the suite raises on purpose."""


class ConfigError(CncError, ValueError):
    """A configuration value, scenario key or parameter is unknown or out of range."""


class ProgramError(CncError, ValueError):
    """A part program is malformed or cannot be executed within the machine's limits."""


class FaultError(CncError, RuntimeError):
    """A run-time fault: non-finite data, a missing message past its timeout, a dead node."""


class InputFault(FaultError):
    """A fault of one input (``input_name``, a topic relative to the node), found perhaps while another arrived."""

    def __init__(self, input_name: str, message: str) -> None:
        super().__init__(message)
        self.input_name = input_name


class BagError(CncError, IOError):
    """A recording is missing, truncated, corrupt or lacks a required topic."""
