"""The force regulator: a law from :data:`FORCE_LAWS`, the override switch, an update period, a preview.

Every ``update_period_s`` the law turns the last force sample into a
requested ratio, the :class:`Quantiser` into the applied ratio, which holds
until the next update (what the CNC's override switch does). Preview plans
(:func:`~cnc_contour_control.force.preview.plan_schedule`, from the depth
schedule the program gives) take over inside their windows: the planned
ratio is requested, the law rests; at a window's end the law restarts from
the model's steady ratio with the new depth as its model depth
(:meth:`ForceLaw.set_depth_mm`).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.force.base import check_sample
from cnc_contour_control.force.preview import StepPlan
from cnc_contour_control.force.quantiser import Quantiser, QuantiserConfig
from cnc_contour_control.force.registry import force_law_config, make_force_law


@dataclass(frozen=True)
class ForceRegulatorConfig:
    """A regulator: law, its parameters, the switch, the update period.

    Parameters
    ----------
    law : str
        Name in :data:`FORCE_LAWS`.
    law_params : Mapping
        Keys of the law's config, validated by building it.
    quantiser : QuantiserConfig or Mapping
        The override switch.
    update_period_s : float
        Period of the override updates [s], in [1e-4, 10].
    hysteresis_fraction : float
        Outside a preview plan, the applied level holds while the request stays within (½ + h) of a level of
        it, h in [0, 5] (0: plain rounding).
    """

    law: str = param("smc", description="force law (registry name)", read_only=True)
    law_params: Mapping[str, Any] = param(default_factory=dict, description="parameters of the law")
    quantiser: QuantiserConfig = param(default_factory=QuantiserConfig, description="the override switch")
    update_period_s: float = param(0.01, unit="s", low=1.0e-4, high=10.0, description="override update period")
    hysteresis_fraction: float = param(0.0, low=0.0, high=5.0,
                                       description="hold the level while the request is within (0.5 + h) levels")

    def __post_init__(self) -> None:
        check_ranges(self, "force_regulator")
        force_law_config(self.law, self.law_params)
        if isinstance(self.quantiser, Mapping):
            object.__setattr__(self, "quantiser", build_config(QuantiserConfig, self.quantiser, context="quantiser"))


class OverrideSample(NamedTuple):
    """One regulator output: requested and applied ratio, and whether this sample updated them."""

    requested_ratio: float
    applied_ratio: float
    updated: bool


class ForceRegulator:
    """Law + quantiser + update period (+ preview plans); ``step`` once per sample of the force."""

    def __init__(self, config: ForceRegulatorConfig, plans: Sequence[StepPlan] = ()) -> None:
        self.config = config
        self.law = make_force_law(config.law, config.law_params)
        self.quantiser = Quantiser(config.quantiser)
        self.plans = tuple(sorted(plans, key=lambda p: p.start_s))
        self._plan: StepPlan | None = None
        self.reset()

    def reset(self, ratio: float = 1.0, t_s: float = 0.0) -> None:
        """Applied ``ratio`` (quantised) at time ``t_s`` [s]; the first step updates."""
        self.t_s, self._since_s, self._plan = t_s, self.config.update_period_s, None
        self.law.reset(ratio)
        applied = self.quantiser(ratio)
        self.last = OverrideSample(ratio, applied, False)
        self.law.note_applied(applied)

    def _planned(self) -> float | None:
        """The planned ratio now, or None; hands back to the law when a window has just ended."""
        plan = next((p for p in self.plans if p.start_s <= self.t_s + 1e-9 < p.end_s), None)
        if plan is None and self._plan is not None:
            self.law.reset(self._plan.ratio_after)
            self.law.set_depth_mm(self._plan.depth_after_mm)
        self._plan = plan
        return None if plan is None else plan.ratio_at(self.t_s + 1e-9)

    def _request(self, force_n: float, reference_n: float) -> tuple[float, bool]:
        """The requested ratio and whether a plan gave it."""
        planned = self._planned() if self.plans else None
        if planned is None:
            return self.law.step(self._since_s, force_n, reference_n), False
        return planned, True

    def _apply(self, requested: float, planned: bool) -> float:
        """The switch's level for ``requested``: the last one while within the hysteresis (not in a plan)."""
        switch, held = self.config.quantiser, self.last.applied_ratio
        band = (0.5 + self.config.hysteresis_fraction) * switch.step_ratio
        if not planned and self.config.hysteresis_fraction > 0.0 and abs(requested - held) < band:
            return held
        return self.quantiser(requested)

    def step(self, dt_s: float, force_n: float, reference_n: float) -> OverrideSample:
        """The force ``force_n`` [N] measured now, ``dt_s`` [s] after the previous sample -> the override."""
        check_sample(dt_s, force_n, reference_n)
        self.t_s += dt_s
        self._since_s += dt_s
        if self._since_s < self.config.update_period_s - 1.0e-9:
            self.last = self.last._replace(updated=False)
            return self.last
        requested, planned = self._request(force_n, reference_n)
        applied = self._apply(requested, planned)
        self.law.note_applied(applied)
        self._since_s = 0.0
        self.last = OverrideSample(requested, applied, True)
        return self.last
