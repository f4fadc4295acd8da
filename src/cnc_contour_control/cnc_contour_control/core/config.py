"""Validation helpers shared by every frozen, validated config of the suite.

Errors name the option, the bound and the value: ``"radius_mm must be > 0, got -3"``.
"""
from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar

import yaml

from cnc_contour_control.core.errors import CncError, ConfigError

T = TypeVar("T")


def _where(name: str, context: str) -> str:
    return f"{context}.{name}" if context else name


def require_finite(name: str, value: float, context: str = "") -> float:
    """Return ``value`` as float, or raise naming ``name`` if it is not a finite number (a bool is no number)."""
    if _is_bool(value):  # float(True) is 1.0: `radius_mm: true` would be a 1 mm circle
        raise ConfigError(f"{_where(name, context)} must be a number, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{_where(name, context)} must be a number, got {value!r}") from err
    if not math.isfinite(number):
        raise ConfigError(f"{_where(name, context)} must be finite, got {value!r}")
    return number


def _is_bool(value: Any) -> bool:
    """True for a Python or numpy boolean."""
    return isinstance(value, bool) or (type(value).__module__ == "numpy" and type(value).__name__ in ("bool", "bool_"))


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
    fields = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]  # cls is a dataclass by contract
    unknown = sorted(set(mapping) - fields)
    if unknown:
        raise ConfigError(
            f"{_where(unknown[0], context)}: unknown key; valid keys are {sorted(fields)}"
        )
    try:
        return cls(**mapping)
    except TypeError as err:
        raise ConfigError(f"{context or cls.__name__}: {err}") from err


#: Largest scenario, program or G-code file read, bytes (4 MiB): far above any real one, and parsed in seconds.
MAX_INPUT_FILE_BYTES = 4 * 1024 * 1024


def read_bounded_bytes(file: Path, what: str, error: type[CncError], limit_bytes: int) -> bytes:
    """The bytes of ``file``, refused unread (``error`` naming ``what``, the file and the limit) past
    ``limit_bytes``, or when it cannot be read."""
    try:
        size = file.stat().st_size
        if size > limit_bytes:
            raise error(f"{what} {str(file)!r} is {size} bytes; the limit is {limit_bytes} bytes "
                        f"({limit_bytes / 2**20:g} MiB)")
        return file.read_bytes()
    except OSError as err:
        raise error(f"{what} {str(file)!r} cannot be read: {err.strerror or err}") from err


def read_text_file(path: str | Path, what: str, error: type[CncError] = ConfigError,
                   limit_bytes: int = MAX_INPUT_FILE_BYTES) -> str:
    """The UTF-8 text of ``path``; ``error`` naming ``what``, the file and the reason otherwise.

    Refused: a missing file, one larger than ``limit_bytes`` (checked before
    reading), and binary content (not UTF-8, or holding NUL bytes).
    """
    file = Path(path)
    if not file.is_file():
        raise error(f"{what} {str(file)!r} does not exist")
    data = read_bounded_bytes(file, what, error, limit_bytes)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise error(f"{what} {str(file)!r} is not a text file (not UTF-8 at byte {err.start})") from err
    if "\0" in text:
        raise error(f"{what} {str(file)!r} is not a text file (NUL character at offset {text.index(chr(0))})")
    return text


def read_yaml_mapping(path: str | Path, what: str, error: type[CncError] = ConfigError) -> dict[str, Any]:
    """The mapping in the YAML file ``path``; ``error`` naming ``what`` and the file otherwise.

    The file is read by :func:`read_text_file` (size limit, text only).
    """
    file = Path(path)
    text = read_text_file(file, what, error)
    try:
        content = load_yaml(text)
    except yaml.YAMLError as err:
        raise error(f"{what} {str(file)!r} is not valid YAML: {_one_line(err)}") from err
    if not isinstance(content, dict):
        raise error(f"{what} {str(file)!r} must hold a mapping, got {type(content).__name__}")
    return content


#: PyYAML's safe loader, libyaml's C implementation when installed (same results, several times faster).
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

_FLOAT_TAG = "tag:yaml.org,2002:float"
#: A float as YAML 1.2 writes it (``1e-3``, ``24e-1``, ``+1.5E+2``, ``1.0e6``), and YAML 1.1's other forms
#: (``1.5``, ``.5``, ``.inf``, ``.nan``, sexagesimal ``1:30.5``). PyYAML's YAML 1.1 resolver needs a dot and a
#: signed exponent, so it reads ``1e-3`` as the string "1e-3".
_FLOAT = re.compile(r"""^(?:[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+
    |[-+]?(?:[0-9][0-9_]*)?\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*\.
    |[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+\.[0-9_]*
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""", re.X)


class YamlLoader(_SAFE_LOADER):  # type: ignore[valid-type,misc]  # the base is chosen at import (C or Python)
    """The safe loader whose floats are YAML 1.2's: ``1e-3`` is the number 0.001, not a string.

    Everything else is PyYAML's safe loading (no Python objects; YAML 1.1
    booleans). Every YAML a user writes (scenarios, ``--set`` values) is read
    with it.
    """


YamlLoader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag != _FLOAT_TAG]
    for first, resolvers in _SAFE_LOADER.yaml_implicit_resolvers.items()}
YamlLoader.add_implicit_resolver(_FLOAT_TAG, _FLOAT, list("-+0123456789."))


def load_yaml(text: str) -> Any:
    """The YAML document ``text``, read by :class:`YamlLoader` (``yaml.YAMLError`` if it is not YAML)."""
    return yaml.load(text, Loader=YamlLoader)


def _one_line(err: Exception) -> str:
    """An error's text on one line."""
    return " ".join(str(err).split())


def require_name(name: str, value: Any) -> str:
    """Return ``value`` if it is a non-empty string, else a ConfigError naming ``name``."""
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{name} must be a non-empty string, got {value!r}")
    return value


def require_names(name: str, values: Any) -> tuple[str, ...]:
    """``values`` as a tuple of unique non-empty strings (at least one), else a ConfigError naming ``name``."""
    if isinstance(values, str) or not isinstance(values, Sequence) or not values:
        raise ConfigError(f"{name} must be a non-empty list of names, got {values!r}")
    names = tuple(require_name(f"{name}[{i}]", v) for i, v in enumerate(values))
    if len(set(names)) != len(names):
        raise ConfigError(f"{name} must be unique, got {list(names)}")
    return names


def require_flag(name: str, value: Any) -> bool:
    """Return ``value`` if it is a bool, else a ConfigError naming ``name``."""
    if not isinstance(value, bool):
        raise ConfigError(f"{name} must be true or false, got {value!r}")
    return value
