"""Validation helpers shared by every frozen, validated config of the suite.

Errors name the option, the bound and the value: ``"radius_mm must be > 0, got -3"``.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml

from cnc_contour_control.errors import CncError, ConfigError

T = TypeVar("T")


def _where(name: str, context: str) -> str:
    return f"{context}.{name}" if context else name


def require_finite(name: str, value: float, context: str = "") -> float:
    """Return ``value`` as float, or raise naming ``name`` if it is not a finite number."""
    try:
        number = float(value)
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{_where(name, context)} must be a number, got {value!r}") from err
    if not math.isfinite(number):
        raise ConfigError(f"{_where(name, context)} must be finite, got {value!r}")
    return number


def require_positive(name: str, value: float, context: str = "") -> float:
    """Return ``value`` if it is finite and > 0."""
    number = require_finite(name, value, context)
    if number <= 0.0:
        raise ConfigError(f"{_where(name, context)} must be > 0, got {value!r}")
    return number


def require_non_negative(name: str, value: float, context: str = "") -> float:
    """Return ``value`` if it is finite and >= 0."""
    number = require_finite(name, value, context)
    if number < 0.0:
        raise ConfigError(f"{_where(name, context)} must be >= 0, got {value!r}")
    return number


def require_range(name: str, value: float, low: float, high: float, context: str = "") -> float:
    """Return ``value`` if ``low <= value <= high``."""
    number = require_finite(name, value, context)
    if not low <= number <= high:
        raise ConfigError(f"{_where(name, context)} must be in [{low}, {high}], got {value!r}")
    return number


def require_choice(name: str, value: str, choices: Mapping[str, Any] | tuple[str, ...], context: str = "") -> str:
    """Return ``value`` if it is one of ``choices`` (a registry or a tuple of names)."""
    valid = sorted(choices)
    if value not in valid:
        raise ConfigError(f"{_where(name, context)} must be one of {valid}, got {value!r}")
    return value


def build_config(cls: type[T], mapping: Mapping[str, Any] | None, context: str = "") -> T:
    """Build the frozen dataclass ``cls`` from ``mapping``; unknown keys are an error.

    The dataclass validates its own values in ``__post_init__``.
    """
    mapping = dict(mapping or {})
    fields = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(mapping) - fields)
    if unknown:
        raise ConfigError(
            f"{_where(unknown[0], context)}: unknown key; valid keys are {sorted(fields)}"
        )
    try:
        return cls(**mapping)
    except TypeError as err:
        raise ConfigError(f"{context or cls.__name__}: {err}") from err


def read_yaml_mapping(path: str | Path, what: str, error: type[CncError] = ConfigError) -> dict[str, Any]:
    """The mapping in the YAML file ``path``; ``error`` naming ``what`` and the file otherwise."""
    file = Path(path)
    if not file.is_file():
        raise error(f"{what} {str(file)!r} does not exist")
    try:
        content = yaml.safe_load(file.read_text())
    except yaml.YAMLError as err:
        raise error(f"{what} {str(file)!r} is not valid YAML: {err}") from err
    if not isinstance(content, dict):
        raise error(f"{what} {str(file)!r} must hold a mapping, got {type(content).__name__}")
    return content
