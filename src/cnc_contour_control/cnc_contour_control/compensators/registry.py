"""The registry of compensators: an explicit table of name -> (config class, builder).

A compensator adds a per-axis correction, in drive units, to the servos'
commands (stage 4 of the tick). A scenario chooses one by name: ``none``
(zeros), ``ccc`` (Koren's cross-coupled controller), ``ilc`` (run-to-run
learning in contour space) or ``neural`` (paper 001's online network). A new
one is a module with a config dataclass (fields declared with
:func:`~cnc_contour_control.core.params.param`) and a class keeping
:class:`~cnc_contour_control.compensators.base.Compensator`, plus one line in
:data:`COMPENSATORS`.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.compensators.base import Compensator, NoCompensatorConfig, ZeroCompensator
from cnc_contour_control.compensators.cross_coupled import CrossCoupledCompensator, CrossCoupledConfig
from cnc_contour_control.compensators.ilc import IlcConfig, IterativeLearningCompensator
from cnc_contour_control.compensators.neural import NeuralCompensator, NeuralConfig
from cnc_contour_control.core.config import build_config, require_choice, require_positive


@dataclass(frozen=True)
class CompensatorEntry:
    """One compensator of the registry.

    Attributes
    ----------
    config_class : type
        Its frozen, validated config dataclass; every field declares unit, range and description.
    build : Callable
        (validated config, axis names, sample period [s]) -> a fresh compensator.
    """

    config_class: type
    build: Callable[[Any, Sequence[str], float], Compensator]


#: Compensators by name.
COMPENSATORS: dict[str, CompensatorEntry] = {
    "none": CompensatorEntry(NoCompensatorConfig, lambda config, axes, _dt: ZeroCompensator(config, axes)),
    "ccc": CompensatorEntry(CrossCoupledConfig, lambda config, axes, _dt: CrossCoupledCompensator(config, axes)),
    "ilc": CompensatorEntry(IlcConfig, IterativeLearningCompensator),
    "neural": CompensatorEntry(NeuralConfig, lambda config, axes, _dt: NeuralCompensator(config, axes)),
}


def compensator_config_class(name: str) -> type:
    """The config class of the compensator ``name``; an unknown name lists the valid ones."""
    require_choice("compensator", name, COMPENSATORS)
    return COMPENSATORS[name].config_class


def compensator_config(name: str, params: Mapping[str, Any] | None = None) -> Any:
    """The validated config of the compensator ``name`` from ``params`` (unknown keys listed and refused)."""
    return build_config(compensator_config_class(name), params or {}, context=name)


def make_compensator(name: str, params: Mapping[str, Any] | None, axis_names: Sequence[str],
                     sample_time_s: float) -> Compensator:
    """Build the compensator ``name`` for ``axis_names`` at ``sample_time_s`` [s] from ``params``.

    Raises
    ------
    ConfigError
        An unknown name (listing the valid ones), an unknown key (listing the
        valid keys), a value out of its range, or a non-positive ``sample_time_s``.
    """
    config = compensator_config(name, params)
    period = require_positive("sample_time_s", sample_time_s, name)
    return COMPENSATORS[name].build(config, tuple(axis_names), period)
