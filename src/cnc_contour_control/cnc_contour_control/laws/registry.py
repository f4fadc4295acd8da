"""The registry of feedback laws: an explicit table of name -> (config class, builder).

A feedback law turns one :class:`~cnc_contour_control.laws.base.LawSample`
(the following error in counts, BLU for paper 000, and the measured and
reference motion) into a feedback command in drive units (DAC for paper 000),
before the servo adds feedforward and compensation, saturates and quantises.
A new law is a module with a config dataclass (fields declared with
:func:`~cnc_contour_control.core.params.param`) and a class keeping
:class:`~cnc_contour_control.laws.base.FeedbackLaw`, plus one line in
:data:`LAWS`.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.laws.base import FeedbackLaw
from cnc_contour_control.laws.disturbance import (
    DobConfig,
    DobLaw,
    DobPdcConfig,
    DobPdcLaw,
    MbdaConfig,
    MbdaLaw,
    MbdaPdcConfig,
    MbdaPdcLaw,
    PdcConfig,
    PdcLaw,
)
from cnc_contour_control.laws.fuzzy import FuzzyConfig, FuzzyLaw
from cnc_contour_control.laws.pdc_stack import FuzzyPdcConfig, FuzzyPdcLaw, PidPdcConfig, PidPdcLaw
from cnc_contour_control.laws.pid import PConfig, PidConfig, PidLaw, PLaw


@dataclass(frozen=True)
class LawEntry:
    """One law of the registry.

    Attributes
    ----------
    config_class : type
        The law's frozen, validated config dataclass (its gains); every field
        declares unit, range and description with ``param(...)``.
    build : Callable
        Validated config -> a fresh law.
    """

    config_class: type
    build: Callable[[Any], FeedbackLaw]


#: Feedback laws by name.
LAWS: dict[str, LawEntry] = {
    "pid": LawEntry(PidConfig, PidLaw),
    "p": LawEntry(PConfig, PLaw),
    "fuzzy": LawEntry(FuzzyConfig, FuzzyLaw),
    "dob": LawEntry(DobConfig, DobLaw),
    "mbda": LawEntry(MbdaConfig, MbdaLaw),
    "pdc": LawEntry(PdcConfig, PdcLaw),
    "dob_pdc": LawEntry(DobPdcConfig, DobPdcLaw),
    "mbda_pdc": LawEntry(MbdaPdcConfig, MbdaPdcLaw),
    "pid_pdc": LawEntry(PidPdcConfig, PidPdcLaw),
    "fuzzy_pdc": LawEntry(FuzzyPdcConfig, FuzzyPdcLaw),
}


def law_config_class(name: str) -> type:
    """The config class of the law ``name``; an unknown name lists the valid ones."""
    require_choice("law", name, LAWS)
    return LAWS[name].config_class


def law_config(name: str, params: Mapping[str, Any] | None = None) -> Any:
    """The validated config of the law ``name`` from ``params`` (unknown keys refused)."""
    return build_config(law_config_class(name), params or {}, context=name)


def make_law(name: str, params: Mapping[str, Any] | None = None) -> FeedbackLaw:
    """Build the law ``name`` from ``params``; an unknown name lists the valid ones."""
    config = law_config(name, params)
    return LAWS[name].build(config)
