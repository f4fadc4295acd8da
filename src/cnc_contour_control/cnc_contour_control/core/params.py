"""Config fields that declare themselves: unit, range, description, read-only (ROS-free).

A config dataclass states each field once::

    @dataclass(frozen=True)
    class PidConfig:
        kp: float = param(2.4, unit="dac/count", low=0.0, high=1e6,
                          description="proportional gain")

:func:`param` is :func:`dataclasses.field` with the metadata under the key
``"param"`` (a :class:`ParamInfo`). :func:`param_specs` lists a config class's
fields as :class:`ParamSpec` (name, type, default, unit, range, description,
read-only, nested config class); the node side
(:mod:`cnc_contour_control.nodes.parameters`) declares ROS parameters from
them and rebuilds the validated config, and the runner writes parameter files
from a config instance with :func:`config_values`. The config's own
``__post_init__`` stays the one validation: the range here is what a ROS
descriptor shows and what ``ros2 param set`` refuses early, and
``test_params`` checks that both agree at the bounds.
"""
from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.config import require_finite, require_range
from cnc_contour_control.core.errors import ConfigError

_KEY = "param"


@dataclass(frozen=True)
class ParamInfo:
    """What a field declares about itself (stored in the field's metadata)."""

    unit: str = ""
    low: float | None = None
    high: float | None = None
    description: str = ""
    read_only: bool = False


def param(default: Any = dataclasses.MISSING, *, unit: str = "", low: float | None = None,
          high: float | None = None, description: str = "", read_only: bool = False,
          default_factory: Any = dataclasses.MISSING) -> Any:
    """A dataclass field with its unit, inclusive range [low, high], description and read-only flag.

    ``read_only`` marks a field whose change needs a restart (a node refuses
    to set it at run time).
    """
    info = ParamInfo(unit, low, high, description, read_only)
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata={_KEY: info})
    return dataclasses.field(default=default, metadata={_KEY: info})


@dataclass(frozen=True)
class ParamSpec:
    """One declared field of a config class.

    Attributes
    ----------
    name : str
        Field name (nested fields of a sub-config are prefixed ``outer.inner`` by
        :func:`flat_specs`).
    kind : type
        ``float``, ``int``, ``bool``, ``str``, ``list`` (of str or float), or ``dict``
        (a free mapping) — the ROS parameter type follows from it.
    default : Any
        The default value (``None`` when the field is required).
    info : ParamInfo
        Unit, range, description, read-only.
    nested : type or None
        The config class of a nested section (``gains`` of a law), else None.
    """

    name: str
    kind: type
    default: Any
    info: ParamInfo
    nested: type | None = None

    @property
    def description(self) -> str:
        """The description with the unit appended (``"proportional gain [dac/count]"``)."""
        unit = f" [{self.info.unit}]" if self.info.unit else ""
        return f"{self.info.description}{unit}".strip()


def _kind(annotation: Any) -> tuple[type, type | None]:
    """The parameter kind of a field annotation, and the nested config class if it is one."""
    origin = typing.get_origin(annotation)
    args = [a for a in typing.get_args(annotation) if a is not type(None)]
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)) and args:
        return _kind(args[0])
    if dataclasses.is_dataclass(annotation):
        return dict, typing.cast(type, annotation)
    if annotation in (float, int, bool, str):
        return annotation, None
    if origin in (tuple, list) or annotation in (tuple, list):
        return list, None
    if origin in (dict, Mapping) or annotation in (dict, Mapping) or str(origin).endswith("Mapping"):
        return dict, None
    return str, None


def param_specs(cls: type) -> tuple[ParamSpec, ...]:
    """The fields of the config dataclass ``cls`` as :class:`ParamSpec`, in declaration order."""
    hints = typing.get_type_hints(cls)
    specs = []
    for f in dataclasses.fields(cls):
        kind, nested = _kind(hints[f.name])
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = None
        specs.append(ParamSpec(f.name, kind, default, f.metadata.get(_KEY, ParamInfo()), nested))
    return tuple(specs)


def flat_specs(cls: type, prefix: str = "") -> tuple[ParamSpec, ...]:
    """:func:`param_specs` with nested config sections expanded into dotted names (``gains.kp``), in order."""
    specs: list[ParamSpec] = []
    for spec in param_specs(cls):
        name = f"{prefix}{spec.name}"
        if spec.nested is not None:
            specs.extend(flat_specs(spec.nested, f"{name}."))
        else:
            specs.append(dataclasses.replace(spec, name=name))
    return tuple(specs)


def config_values(config: Any) -> dict[str, Any]:
    """A config instance as plain values in its own units (nested configs as mappings, tuples as lists)."""
    return {f.name: _plain(getattr(config, f.name)) for f in dataclasses.fields(config)}


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return config_values(value)
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return value
    return value


#: Annotations of the numeric fields (``from __future__ import annotations`` makes them strings).
_NUMBER_TYPES = (float, int, "float", "int", "float | None", "int | None")


def check_ranges(config: Any, context: str = "") -> None:
    """Validate every numeric field of ``config`` against its declared range (call from ``__post_init__``).

    A field whose :class:`ParamInfo` has ``low`` and/or ``high`` must be a
    finite number within them; it is stored back as a float (an int field
    keeps its value). Errors name the option, the bound and the value:
    ``"pid.kp must be in [0.0, 1000000.0], got -1"``. So the declared range is
    the validation, written once.
    """
    for f in dataclasses.fields(config):
        info = f.metadata.get(_KEY)
        if info is None:
            continue
        value, where = getattr(config, f.name), f"{context}.{f.name}" if context else f.name
        if isinstance(value, bool) and f.type in _NUMBER_TYPES:  # a bool is no number, bounded or not
            raise ConfigError(f"{where} must be a number, got {value!r}")
        if info.low is None and info.high is None:
            continue
        if isinstance(value, (bool, str)):  # a string "1e-3" is not the number: the nodes would refuse it too
            raise ConfigError(f"{where} must be a number, got {value!r}")
        number = require_finite(f.name, value, context)
        if info.low is not None and info.high is not None:
            require_range(f.name, value, info.low, info.high, context)
        elif info.low is not None and number < info.low:
            raise ConfigError(f"{where} must be >= {info.low}, got {value!r}")
        elif info.high is not None and number > info.high:
            raise ConfigError(f"{where} must be <= {info.high}, got {value!r}")
        if f.type in (float, "float"):
            object.__setattr__(config, f.name, number)


def declared_bounds(cls: type) -> list[tuple[ParamSpec, float, float]]:
    """Every numeric bound of ``cls`` (nested sections flattened): (spec, bound, direction out of range: -1 or +1)."""
    return [(spec, bound, direction) for spec in flat_specs(cls) if spec.kind in (float, int)
            for bound, direction in ((spec.info.low, -1.0), (spec.info.high, 1.0)) if bound is not None]
