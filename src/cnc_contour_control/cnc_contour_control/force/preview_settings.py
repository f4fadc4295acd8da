"""The preview as a run configures it: the depth schedule given with the program, the model to plan on (ROS-free).

A scenario's ``force_regulator.preview`` section, the force-regulator node's
``preview.*`` parameters and the engine's stage build the same
:class:`PreviewSettings`; its :meth:`~PreviewSettings.plans` are the
:func:`~cnc_contour_control.force.preview.plan_schedule` of that schedule,
handed to the :class:`~cnc_contour_control.force.regulator.ForceRegulator`::

    force_regulator:
      preview: {depth_schedule: [[0, 1], [4, 2], [8, 3]], model: {interpolator_tau_s: 0.17}}

The schedule is the program's knowledge, not the plant's: it may differ from
``plant.cutting``'s (a wrong schedule shows robustness). Without the section,
``enabled`` is false and there are no plans. The schedule is two flat lists,
as ROS parameters need (``depth_schedule: [[t_s, depth_mm], ...]`` is split).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.config import build_config, require_finite
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.force_model import DepthSchedule, TurningModelConfig
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.force.preview import PreviewConfig, StepPlan, plan_schedule
from cnc_contour_control.force.regulator import ForceRegulatorConfig


@dataclass(frozen=True)
class PreviewSettings:
    """The preview of a run.

    Parameters
    ----------
    enabled : bool
        Plan around the schedule's depth steps (False: feedback alone).
    depth_schedule_t_s : tuple of float
        Times [s] of the depth schedule the program gives, strictly increasing.
    depth_schedule_mm : tuple of float
        Depth of cut [mm] from each time on (>= 0), one per time.
    model : TurningModelConfig or Mapping
        The nominal model the plans are made on (Eqs. 1-4).
    window : PreviewConfig or Mapping
        The planning window around each step and the plan's weights.
    """

    enabled: bool = param(False, read_only=True, description="preview plans from the depth schedule")
    depth_schedule_t_s: tuple[float, ...] = param((0.0,), unit="s", read_only=True,
                                                  description="times of the program's depth schedule")
    depth_schedule_mm: tuple[float, ...] = param((1.0,), unit="mm", read_only=True,
                                                 description="depth of cut from each schedule time on")
    model: TurningModelConfig = param(default_factory=TurningModelConfig, read_only=True,
                                      description="nominal model the plans are made on")
    window: PreviewConfig = param(default_factory=PreviewConfig, read_only=True,
                                  description="planning window and weights")

    def __post_init__(self) -> None:
        check_ranges(self, "preview")
        for name, cls in (("model", TurningModelConfig), ("window", PreviewConfig)):
            value = getattr(self, name)
            if isinstance(value, Mapping):
                object.__setattr__(self, name, build_config(cls, value, context=f"preview.{name}"))
            elif not isinstance(value, cls):
                raise ConfigError(f"preview.{name} must be a mapping, got {value!r}")
        times, depths = (tuple(require_finite(f"{n}[{k}]", v, "preview") for k, v in enumerate(getattr(self, n)))
                         for n in ("depth_schedule_t_s", "depth_schedule_mm"))  # a bool is no number
        if len(times) != len(depths):
            raise ConfigError(f"preview.depth_schedule_mm must have one depth per time ({len(times)}), "
                              f"got {len(depths)}")
        try:
            DepthSchedule(tuple(zip(times, depths)))
        except ConfigError as err:
            raise ConfigError(f"preview.{err}") from err
        object.__setattr__(self, "depth_schedule_t_s", times)
        object.__setattr__(self, "depth_schedule_mm", depths)

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], context: str = "preview") -> PreviewSettings:
        """The section as a scenario writes it: enabled unless it says not, ``depth_schedule`` pairs split."""
        if not isinstance(mapping, Mapping):
            raise ConfigError(f"{context} must be a mapping, got {mapping!r}")
        values = {"enabled": True, **mapping}
        if "depth_schedule" in values:
            rows = values.pop("depth_schedule")
            if isinstance(rows, (str, bytes)) or not isinstance(rows, Sequence) or not all(
                    isinstance(r, Sequence) and not isinstance(r, str) and len(r) == 2 for r in rows):
                raise ConfigError(f"{context}.depth_schedule must be a list of [t_s, depth_mm] pairs, got {rows!r}")
            values["depth_schedule_t_s"], values["depth_schedule_mm"] = [r[0] for r in rows], [r[1] for r in rows]
        return build_config(cls, values, context=context)

    def schedule(self) -> DepthSchedule:
        """The program's depth schedule."""
        return DepthSchedule(tuple(zip(self.depth_schedule_t_s, self.depth_schedule_mm)))

    def plans(self, reference_n: float, regulator: ForceRegulatorConfig) -> tuple[StepPlan, ...]:
        """The plan of each depth step at ``reference_n`` [N] on the regulator's period and switch (none if off)."""
        if not self.enabled:
            return ()
        return plan_schedule(self.model, self.schedule(), reference_n, regulator.update_period_s,
                             regulator.quantiser, self.window)
