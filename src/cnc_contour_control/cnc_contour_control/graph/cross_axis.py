"""The cross-axis stages as a run configures them: which estimator and compensator, with what (ROS-free).

A scenario's ``estimator`` and ``compensator`` sections, the estimator and
compensator nodes' parameters and the engine's stages are all built from these
two classes, so the three accept the same values::

    estimator:   {method: window, params: {memory_points: 4096}}
    compensator: {method: neural, params: {eta: 0.0005}, state_in: w.npz, state_out: w.npz, freeze: false}

``method`` names an entry of :data:`~cnc_contour_control.estimators.ESTIMATORS`
or :data:`~cnc_contour_control.compensators.COMPENSATORS`; ``params`` are
that entry's config fields, validated by building the config (an unknown key
is an error listing the valid ones). A compensator's learned state (weights,
a learned feed-forward) is loaded from ``state_in`` when the run starts and
written to ``state_out`` when the run finishes (after ``end_run``, where the
run-to-run learners update), so learning carries over from run to run.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cnc_contour_control.compensators import COMPENSATORS, Compensator, compensator_config_class, make_compensator
from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import config_values, param
from cnc_contour_control.estimators import ESTIMATORS, ContourEstimator, estimator_config_class, make_estimator
from cnc_contour_control.motion.geometry import Program


def _checked_params(params: Any, context: str) -> dict[str, Any]:
    if params is None:
        return {}
    if not isinstance(params, Mapping):
        raise ConfigError(f"{context}.params must be a mapping, got {params!r}")
    return dict(params)


@dataclass(frozen=True)
class EstimatorSettings:
    """The run's contour-error estimator: a registry name and its parameters.

    Parameters
    ----------
    method : str
        Name in :data:`~cnc_contour_control.estimators.ESTIMATORS`.
    params : Mapping
        The method's config fields (its config class's defaults for the rest).
    """

    method: str = param("window", read_only=True, description="contour-error estimator (registry name)")
    params: Mapping[str, Any] = param(default_factory=dict, read_only=True,
                                      description="the estimator's parameters (its config's fields)")

    def __post_init__(self) -> None:
        require_choice("method", self.method, ESTIMATORS)
        params = _checked_params(self.params, "estimator")
        config: object = build_config(estimator_config_class(self.method), params,
                                      context=f"estimator.params[{self.method}]")
        object.__setattr__(self, "params", config_values(config))

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], context: str = "estimator") -> EstimatorSettings:
        """Build from a mapping; unknown keys are an error listing the valid ones."""
        return build_config(cls, mapping, context=context)

    def make(self, program: Program) -> ContourEstimator:
        """A fresh estimator for ``program``."""
        return make_estimator(self.method, self.params, program)


@dataclass(frozen=True)
class CompensatorSettings:
    """The run's compensator: a registry name, its parameters, and where its learned state comes from and goes.

    Parameters
    ----------
    method : str
        Name in :data:`~cnc_contour_control.compensators.COMPENSATORS`.
    params : Mapping
        The method's config fields.
    state_in : str
        ``.npz`` file to start from (learned weights or feed-forward); empty: start fresh.
    state_out : str
        ``.npz`` file written when the run finishes; empty: none.
    freeze : bool
        Apply the compensation without learning.
    """

    method: str = param("neural", read_only=True, description="compensator (registry name: none, ccc, ilc, neural)")
    params: Mapping[str, Any] = param(default_factory=dict, read_only=True,
                                      description="the compensator's parameters (its config's fields)")
    state_in: str = param("", read_only=True, description="learned state (.npz) to start from; empty: fresh")
    state_out: str = param("", read_only=True, description="file (.npz) the learned state is written to "
                                                           "when the run finishes; empty: none")
    freeze: bool = param(False, description="apply the compensation without learning")

    def __post_init__(self) -> None:
        require_choice("method", self.method, COMPENSATORS)
        params = _checked_params(self.params, "compensator")
        config: object = build_config(compensator_config_class(self.method), params,
                                      context=f"compensator.params[{self.method}]")
        object.__setattr__(self, "params", config_values(config))
        for name in ("state_in", "state_out"):
            value = getattr(self, name)
            if not isinstance(value, str) or (value and not value.endswith(".npz")):
                raise ConfigError(f"compensator.{name} must be a path ending in .npz (or empty), got {value!r}")
        if not isinstance(self.freeze, bool):
            raise ConfigError(f"compensator.freeze must be true or false, got {self.freeze!r}")

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], context: str = "compensator") -> CompensatorSettings:
        """Build from a mapping; unknown keys are an error listing the valid ones."""
        return build_config(cls, mapping, context=context)

    def make(self, axis_names: Sequence[str], sample_time_s: float) -> Compensator:
        """A compensator for a run: built, its state loaded from ``state_in`` (if given), frozen if asked."""
        compensator = make_compensator(self.method, self.params, axis_names, sample_time_s)
        if self.state_in:
            compensator.load(Path(self.state_in))
        compensator.frozen = self.freeze
        compensator.reset()
        return compensator

    def finish(self, compensator: Compensator) -> Path | None:
        """After a finished run: the run-to-run update (``end_run``), then the state to ``state_out``; its path."""
        compensator.end_run()
        if not self.state_out:
            return None
        path = Path(self.state_out)
        path.parent.mkdir(parents=True, exist_ok=True)
        compensator.save(path)
        return path
