"""The force regulator as a run configures it: set point and regulator (ROS-free).

A scenario's ``force_regulator`` section, the force-regulator node's parameters
and the engine's stage are all built from these classes, so the three accept
the same values::

    force_regulator: {reference_n: 500, law: smc, law_params: {lambda_per_s: 20},
                      quantiser: {step_ratio: 0.1, max_ratio: 1.5}, update_period_s: 0.01}

:class:`ForceSetpoint` holds what the run adds to the regulator's own config
(the reference force and the stale-input timeout), :class:`PreviewSettings`
the program's depth schedule for the preview (``preview``, optional);
:class:`~cnc_contour_control.force.regulator.ForceRegulatorConfig` the rest
(law from :data:`~cnc_contour_control.force.FORCE_LAWS`, its parameters, the
override switch, the update period). The node declares the two as parameters
(the law's config as ``law_params.*``); the section is flat, split here.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, config_values, param
from cnc_contour_control.force.preview_settings import PreviewSettings
from cnc_contour_control.force.registry import force_law_config
from cnc_contour_control.force.regulator import ForceRegulator, ForceRegulatorConfig


@dataclass(frozen=True)
class ForceSetpoint:
    """The regulator's set point and how long the force may stay away.

    Parameters
    ----------
    reference_n : float
        The cutting-force reference [N], in [1e-3, 1e7].
    stale_timeout_s : float
        Wall time without a force sample after which the node reports STALE and holds the last applied
        override [s], in [0.01, 3600].
    """

    reference_n: float = param(500.0, unit="N", low=1.0e-3, high=1.0e7, read_only=True,
                               description="cutting-force reference")
    stale_timeout_s: float = param(1.0, unit="s", low=0.01, high=3600.0, read_only=True,
                                   description="wall time without cutting_force before the status is STALE")

    def __post_init__(self) -> None:
        check_ranges(self, "force_regulator")


#: The optional section of the program's depth schedule (:class:`PreviewSettings`).
PREVIEW = "preview"
_SETPOINT_KEYS = tuple(f.name for f in dataclasses.fields(ForceSetpoint))
_REGULATOR_KEYS = tuple(f.name for f in dataclasses.fields(ForceRegulatorConfig))


@dataclass(frozen=True)
class ForceRegulatorSettings:
    """The run's force regulator: set point and regulator config."""

    setpoint: ForceSetpoint
    regulator: ForceRegulatorConfig
    preview: PreviewSettings = PreviewSettings()

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any] | None,
                     context: str = "force_regulator") -> ForceRegulatorSettings:
        """Build from the flat section; an unknown key lists the valid ones."""
        if mapping is not None and not isinstance(mapping, Mapping):
            raise ConfigError(f"{context} must be a mapping, got {mapping!r}")
        values = dict(mapping or {})
        unknown = sorted(set(values) - {*_SETPOINT_KEYS, *_REGULATOR_KEYS, PREVIEW})
        if unknown:
            raise ConfigError(f"{context}.{unknown[0]}: unknown key; valid keys are "
                              f"{sorted({*_SETPOINT_KEYS, *_REGULATOR_KEYS, PREVIEW})}")
        try:
            setpoint = build_config(ForceSetpoint, {k: v for k, v in values.items() if k in _SETPOINT_KEYS})
            regulator = build_config(ForceRegulatorConfig, {k: v for k, v in values.items() if k in _REGULATOR_KEYS})
            preview = PreviewSettings() if values.get(PREVIEW) is None else PreviewSettings.from_mapping(
                values[PREVIEW], PREVIEW)
        except ConfigError as err:
            raise ConfigError(f"{context}: {err}") from err
        return cls(setpoint, regulator, preview)

    def values(self) -> dict[str, Any]:
        """Plain values under the node's parameter names (the law's config complete, as ``law_params``)."""
        regulator = config_values(self.regulator)
        regulator["law_params"] = config_values(force_law_config(self.regulator.law, self.regulator.law_params))
        return {**config_values(self.setpoint), **regulator, PREVIEW: config_values(self.preview)}

    def make(self) -> ForceRegulator:
        """A fresh regulator (applied ratio 1 until its first update), with the preview's plans."""
        return ForceRegulator(self.regulator, self.preview.plans(self.setpoint.reference_n, self.regulator))
