"""The registry of force laws: an explicit table of name -> (config class, builder)."""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.force.adaptive import AdaptiveConfig, AdaptiveLaw
from cnc_contour_control.force.base import ForceLaw
from cnc_contour_control.force.pi import PiConfig, PiLaw
from cnc_contour_control.force.smc import SmcConfig, SmcLaw
from cnc_contour_control.force.smc_integral import SmcIntegralConfig, SmcIntegralLaw


@dataclass(frozen=True)
class ForceLawEntry:
    """One force law: its validated config class and config -> fresh law."""

    config_class: type
    build: Callable[[Any], ForceLaw]


#: Force laws by name.
FORCE_LAWS: dict[str, ForceLawEntry] = {
    "smc": ForceLawEntry(SmcConfig, SmcLaw),
    "smc_integral": ForceLawEntry(SmcIntegralConfig, SmcIntegralLaw),
    "adaptive": ForceLawEntry(AdaptiveConfig, AdaptiveLaw),
    "pi": ForceLawEntry(PiConfig, PiLaw),
}


def force_law_config(name: str, params: Mapping[str, Any] | None = None) -> Any:
    """The validated config of the force law ``name``; an unknown name or key lists the valid ones."""
    require_choice("force_law", name, FORCE_LAWS)
    return build_config(FORCE_LAWS[name].config_class, params or {}, context=name)


def make_force_law(name: str, params: Mapping[str, Any] | None = None) -> ForceLaw:
    """Build the force law ``name`` from ``params``."""
    config = force_law_config(name, params)
    return FORCE_LAWS[name].build(config)
