"""A tuning problem's parts: design variables (dotted scenario paths with bounds) and constraints.

A design variable ``servo.law_params.kp=0.5:8`` names a scenario key the way
``cnc-contour run --set`` does; its value at a point is deep-merged into the
scenario (:meth:`Scenario.variant`). A ``*`` part stands for every axis of the
scenario (``plant.axis_overrides.*.ki``: one value for K1 on all axes). A constraint ``phase_margin_deg>=45``
names a figure of :data:`cnc_tools.tuning.objectives.CONSTRAINT_FIGURES`, an
operator and a bound.
"""
from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.errors import ConfigError

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_VARIABLE = re.compile(rf"^(?P<path>[A-Za-z_][\w.*]*)=(?P<low>{_NUMBER}):(?P<high>{_NUMBER})$")
_CONSTRAINT = re.compile(rf"^(?P<name>[A-Za-z_]\w*)(?P<op>>=|<=)(?P<bound>{_NUMBER})$")


@dataclass(frozen=True)
class DesignVariable:
    """A scenario key (dotted path) searched in ``[low, high]``."""

    path: str
    low: float
    high: float

    def __post_init__(self) -> None:
        if not all(self.path.split(".")):
            raise ConfigError(f"design variable path must be dotted names like servo.law_params.kp, got {self.path!r}")
        for name in ("low", "high"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigError(f"design variable {self.path}: {name} must be finite, got {getattr(self, name)}")
        if self.low > self.high:
            raise ConfigError(f"design variable {self.path}: lower bound must be <= upper bound, "
                              f"got {self.low} > {self.high}")


@dataclass(frozen=True)
class Constraint:
    """``figure op bound``, e.g. phase_margin_deg >= 45."""

    figure: str
    op: str
    bound: float

    def __post_init__(self) -> None:
        if self.op not in (">=", "<="):
            raise ConfigError(f"constraint {self.figure}: operator must be >= or <=, got {self.op!r}")

    def violation(self, value: float) -> float:
        """How far ``value`` is outside the constraint (0 when it holds; inf for a non-finite value)."""
        if math.isnan(value):
            return math.inf
        gap = self.bound - value if self.op == ">=" else value - self.bound
        return max(0.0, gap)

    def __str__(self) -> str:
        return f"{self.figure}{self.op}{self.bound:g}"


def parse_variable(text: str) -> DesignVariable:
    """``PATH=LO:HI`` -> :class:`DesignVariable`; ConfigError says the form on anything else."""
    match = _VARIABLE.match(text.strip())
    if match is None:
        raise ConfigError(f"--var takes PATH=LO:HI (e.g. servo.law_params.kp=0.5:8), got {text!r}")
    return DesignVariable(match["path"], float(match["low"]), float(match["high"]))


def parse_constraint(text: str) -> Constraint:
    """``NAME>=BOUND`` or ``NAME<=BOUND`` -> :class:`Constraint`."""
    match = _CONSTRAINT.match(text.replace(" ", ""))
    if match is None:
        raise ConfigError(f"--constraint takes NAME>=BOUND or NAME<=BOUND (e.g. phase_margin_deg>=45), got {text!r}")
    return Constraint(match["name"], match["op"], float(match["bound"]))


def check_unique(variables: Sequence[DesignVariable]) -> None:
    """Refuse an empty list or a path given twice."""
    if not variables:
        raise ConfigError("tuning needs at least one design variable (--var PATH=LO:HI)")
    paths = [v.path for v in variables]
    twice = sorted({p for p in paths if paths.count(p) > 1})
    if twice:
        raise ConfigError(f"design variable {twice[0]} is given more than once")


def expand(path: str, axes: Sequence[str]) -> list[str]:
    """``path`` with each ``*`` part replaced by every axis name (the path itself when it has none)."""
    if "*" not in path.split("."):
        return [path]
    if not axes:
        raise ConfigError(f"design variable {path}: '*' stands for the axes, but no axes are known")
    head, _, tail = path.partition("*")
    return [p for axis in axes for p in expand(f"{head}{axis}{tail}", axes)]


def overrides_of(variables: Sequence[DesignVariable], values: Sequence[float],
                 axes: Sequence[str] = ()) -> dict[str, Any]:
    """The nested override mapping that sets each variable's path (``*`` expanded over ``axes``) to its value."""
    result: dict[str, Any] = {}
    for variable, value in zip(variables, values, strict=True):
        for path in expand(variable.path, axes):
            node = result
            *parents, leaf = path.split(".")
            for part in parents:
                node = node.setdefault(part, {})
            node[leaf] = float(value)
    return result


def lookup(mapping: Mapping[str, Any], path: str) -> Any:
    """The value at a dotted ``path`` of nested mappings, or None when a part is missing.

    A ``*`` part takes the first entry that has the rest of the path.
    """
    head, _, rest = path.partition(".")
    if not isinstance(mapping, Mapping):
        return None
    if head == "*":
        found = (lookup(value, rest) for value in mapping.values())
        return next((f for f in found if f is not None), None)
    if head not in mapping:
        return None
    return lookup(mapping[head], rest) if rest else mapping[head]
