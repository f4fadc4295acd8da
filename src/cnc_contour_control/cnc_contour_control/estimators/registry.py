"""The registry of contour-error estimators: an explicit table of name -> (config class, builder).

``window`` is paper 001's variable-window search over the stored references
(:mod:`.window`); ``path`` measures against the programmed segment, as the
scorer does (:mod:`.path`). A new estimator is a module with a config
dataclass (fields declared with :func:`~cnc_contour_control.core.params.param`) and
a class keeping :class:`~cnc_contour_control.estimators.base.ContourEstimator`,
plus one line in :data:`ESTIMATORS`.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.estimators.base import ContourEstimator
from cnc_contour_control.estimators.path import PathEstimator, PathEstimatorConfig
from cnc_contour_control.estimators.window import WindowEstimator, WindowEstimatorConfig
from cnc_contour_control.motion.geometry import Program


@dataclass(frozen=True)
class EstimatorEntry:
    """One estimator of the registry.

    Attributes
    ----------
    config_class : type
        The estimator's frozen, validated config dataclass.
    build : Callable
        ``(validated config, program) -> a fresh estimator``.
    """

    config_class: type
    build: Callable[[Any, Program], ContourEstimator]


def _window(config: WindowEstimatorConfig, program: Program) -> WindowEstimator:
    """The window estimator uses only the program's axes (it learns the contour from the references)."""
    return WindowEstimator(config, program.n_axes, program.axis_names)


#: Contour-error estimators by name.
ESTIMATORS: dict[str, EstimatorEntry] = {
    "window": EstimatorEntry(WindowEstimatorConfig, _window),
    "path": EstimatorEntry(PathEstimatorConfig, PathEstimator),
}


def estimator_config_class(name: str) -> type:
    """The config class of the estimator ``name``; an unknown name lists the valid ones."""
    require_choice("estimator", name, ESTIMATORS)
    return ESTIMATORS[name].config_class


def estimator_config(name: str, params: Mapping[str, Any] | None = None) -> Any:
    """The validated config of the estimator ``name`` from ``params`` (unknown keys refused, listing the valid ones)."""
    return build_config(estimator_config_class(name), params or {}, context=name)


def make_estimator(name: str, params: Mapping[str, Any] | None, program: Program) -> ContourEstimator:
    """Build the estimator ``name`` from ``params`` for ``program``; an unknown name lists the valid ones."""
    config = estimator_config(name, params)
    return ESTIMATORS[name].build(config, program)
